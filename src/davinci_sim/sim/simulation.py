"""The simulation: a MuJoCo model of the da Vinci system stepped at 1 kHz with dVRK arms.

Each :meth:`Simulation.tick` runs: components' ``pre_step`` (console, teleoperation …) → arm
setpoints (trajectories, wrench-to-effort) → joint servo (PD + gravity compensation) → one
``mj_step`` of 1 ms → components' ``post_step`` (haptic force fields …). Arms read their state
from MuJoCo on demand, so a tick costs only what the physics and the active setpoints need.
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco
import numpy as np

from davinci_sim.geometry.se3 import invert_transform
from davinci_sim.kinematics import fk
from davinci_sim.kinematics.arms import load_arm, load_suj
from davinci_sim.kinematics.suj import T_cart_rcm
from davinci_sim.model import build_spec, resolve_scene
from davinci_sim.sim.arm import Arm
from davinci_sim.sim.arms import ECM, MTM, PSM, SUJArm
from davinci_sim.sim.sensors import INSTRUMENT_BODIES, CameraRenderer, body_ids, contact_force
from davinci_sim.sim.servo import JointServo

ARM_NAMES = ("PSM1", "PSM2", "PSM3", "ECM", "MTML", "MTMR")
#: Default base frames (and the camera frame) are reused while the joints they depend on
#: move by less than this (rad or m) from where they were computed: the setup joints yield a
#: little (~1e-5 rad/s) under the arms' reaction forces, and recomputing their chains every
#: tick costs the 1 kHz loop ~40 µs. The error is at most ~1.5 µm at the tool tip (1.5 m of
#: lever), far below what the dVRK's setup-joint potentiometers resolve.
BASE_FRAME_TOLERANCE = 1e-6
_ARM_CLASSES = {"PSM": PSM, "ECM": ECM, "MTM": MTM}


def _has_joint(model: mujoco.MjModel, name: str) -> bool:
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name) >= 0


class Simulation:
    """The whole simulated system.

    Args:
        scene: a scene name of :data:`davinci_sim.model.SCENES` (``"full"`` …) or a
            ``SceneConfig``.
        seed: seeds :attr:`rng`, the only source of randomness (encoder noise, and what
            tasks and operators draw); the same seed and commands give the same trajectory.
        encoder_noise_std: standard deviation of the noise added to measured joint
            positions (rad or m), 0 by default. The servo itself sees the true positions.
        keyframe: initial state: ``"home"`` (SUJ at the dVRK simulated positions, dvrk.md
            1.6; arms at their simulated home, dvrk.md 1.7) or ``"surgical"`` (the same with
            the ECM's setup joints posed so that the endoscope sees the instruments).
        edit_spec: called with the scene's ``MjSpec`` before it is compiled, to add what a
            task needs (visual path, objects). It must not add joints or actuators.
        **scene_overrides: passed to :func:`davinci_sim.model.build_model`.
    """

    def __init__(
        self,
        scene="full",
        *,
        seed: int = 0,
        encoder_noise_std: float = 0.0,
        keyframe: str = "home",
        edit_spec: Callable[[mujoco.MjSpec], None] | None = None,
        **scene_overrides,
    ) -> None:
        self.config = resolve_scene(scene, **scene_overrides)
        self.endoscope = self.config.endoscope
        spec = build_spec(self.config)
        if edit_spec is not None:
            edit_spec(spec)  # e.g. draw a task's path (tasks.add_path_visual)
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        key = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_KEY, keyframe)
        if key < 0:
            names = [self.model.key(i).name for i in range(self.model.nkey)]
            raise ValueError(f"unknown keyframe {keyframe!r}; keyframes: {names}")
        mujoco.mj_resetDataKeyframe(self.model, self.data, key)
        self.dt = float(self.model.opt.timestep)
        self.seed = seed
        self.rng = np.random.default_rng(seed)
        if not (np.isfinite(encoder_noise_std) and encoder_noise_std >= 0):
            raise ValueError(f"encoder_noise_std must be >= 0, got {encoder_noise_std!r}")
        self.encoder_noise_std = float(encoder_noise_std)
        self.tick_count = 0
        self._suj = load_suj()
        mujoco.mj_forward(self.model, self.data)
        self.servo = JointServo(self.model)
        self._noisy_qpos: np.ndarray | None = None
        self._base_frames: dict[str, tuple[int, np.ndarray, object]] = {}
        self._base_adr: dict[str, np.ndarray] = {}
        self.arms: dict[str, Arm] = {}
        for name in ARM_NAMES:
            kin = load_arm(name)
            if _has_joint(self.model, f"{name}/{kin.chain.joint_names[0]}"):
                self.arms[name] = _ARM_CLASSES[kin.arm_type](name, kin, self)
        for name, suj in self._suj.items():
            if _has_joint(self.model, f"SUJ/{name}/J0"):
                self.arms[f"SUJ/{name}"] = SUJArm(f"SUJ/{name}", suj, self)
        # Fingers (PSM jaws, MTM grippers) hold their initial opening.
        self.servo.q_ref[:] = self.data.qpos[self.servo.qposadr]
        self._instrument_bodies = {
            name: body_ids(self.model, [f"{name}/{b}" for b in INSTRUMENT_BODIES[arm.kin.arm_type]])
            for name, arm in self.arms.items()
            if arm.kin.arm_type in INSTRUMENT_BODIES
        }
        self._cameras: CameraRenderer | None = None
        self.components: dict[str, object] = {}
        """Other parts ticked with the arms (console, teleops …), by name. Each has
        ``pre_step(t)`` (called before the arms, every tick, in registration order),
        ``snapshot()`` and optionally ``post_step(t)`` (called after the physics step with the
        new time, e.g. to compute haptic forces from the state the step produced)."""

    # ------------------------------------------------------------ time
    @property
    def time(self) -> float:
        """Simulation time in s."""
        return float(self.data.time)

    def tick(self) -> None:
        """One 1 ms control tick: components → arm setpoints → servo → physics → components."""
        t = self.data.time
        for component in self.components.values():
            component.pre_step(t)
        for arm in self.arms.values():
            arm._pre_step(t)
        self.servo.apply(self.data)
        mujoco.mj_step(self.model, self.data)
        self.tick_count += 1
        if self.encoder_noise_std > 0:
            self._noisy_qpos = self.data.qpos + self.rng.normal(
                0.0, self.encoder_noise_std, self.data.qpos.shape
            )
        t = self.data.time
        for component in self.components.values():
            post_step = getattr(component, "post_step", None)
            if post_step is not None:
                post_step(t)

    def step(self, n: int = 1) -> None:
        """``n`` ticks."""
        for _ in range(n):
            self.tick()

    def run_for(self, seconds: float) -> None:
        """Tick for ``seconds`` of simulation time."""
        self.step(max(0, round(seconds / self.dt)))

    def run_until(self, predicate, timeout: float) -> bool:
        """Tick until ``predicate()`` is true or ``timeout`` s of sim time pass; returns it."""
        end = self.time + timeout
        while not predicate():
            if self.time >= end:
                return False
            self.tick()
        return True

    def measured_qpos(self) -> np.ndarray:
        """Joint positions as the encoders read them (with noise when enabled)."""
        return self.data.qpos if self._noisy_qpos is None else self._noisy_qpos

    # ------------------------------------------------------------ frames
    def _T_cart_rcm(self, arm: str) -> np.ndarray:
        return T_cart_rcm(self._suj[arm], self.arms[f"SUJ/{arm}"].measured_jp())

    def default_base_frame(self, arm: str) -> tuple[np.ndarray, str]:
        """Base frame of ``arm`` as the dVRK system computes it (dvrk.md 1.6, 1.5).

        PSM: its RCM in the ECM tip (camera) frame, reference ``ECM``; ECM: its RCM in the
        cart, reference ``Cart``; MTM: its base in ``HRSV``; SUJ arm: its base in the cart.
        """
        return self._cached_frame(arm, self._compute_base_frame)

    def T_cart_camera(self) -> np.ndarray:
        """The ECM tip (camera frame) in the cart (world) frame, 4x4, m (dvrk.md 1.6)."""
        if "ECM" not in self.arms:
            raise KeyError("no ECM in this simulation: there is no camera frame")
        return self._cached_frame("camera", self._compute_camera_frame)

    def _cached_frame(self, key: str, compute):
        # Cached per tick, and across ticks while the joints it depends on stay within
        # BASE_FRAME_TOLERANCE: teleoperation and haptics ask for these frames many times per
        # tick, and the setup joints and the ECM are mostly still.
        entry = self._base_frames.get(key)
        if entry is not None and entry[0] == self.tick_count:
            return entry[2]
        q = self.measured_qpos()[self._base_qposadr(key)]
        if entry is not None and (
            q.size == 0 or np.abs(q - entry[1]).max() <= BASE_FRAME_TOLERANCE
        ):
            self._base_frames[key] = (self.tick_count, entry[1], entry[2])
            return entry[2]
        result = compute(key)
        self._base_frames[key] = (self.tick_count, q.copy(), result)
        return result

    def _base_qposadr(self, arm: str) -> np.ndarray:
        """qpos addresses of the joints ``arm``'s default base frame depends on."""
        adr = self._base_adr.get(arm)
        if adr is None:
            kin_type = "camera" if arm == "camera" else self.arms[arm].kin.arm_type
            names = []
            if kin_type == "camera":
                names = ["SUJ/ECM", "ECM"]
            elif kin_type in ("PSM", "ECM") and f"SUJ/{arm}" in self.arms:
                names = ["SUJ/ECM", "ECM", f"SUJ/{arm}"] if kin_type == "PSM" else ["SUJ/ECM"]
            names = [n for n in names if n in self.arms]
            parts = [self.arms[n]._qposadr for n in names]
            adr = np.concatenate(parts) if parts else np.zeros(0, dtype=int)
            self._base_adr[arm] = adr
        return adr

    def _compute_base_frame(self, arm: str) -> tuple[np.ndarray, str]:
        kin_type = self.arms[arm].kin.arm_type
        if kin_type == "MTM":
            result = (self.arms[arm].kin.T_reference_base, "HRSV")
        elif kin_type == "SUJ":
            result = (self._suj[arm.split("/", 1)[1]].T_cart_sujbase, "Cart")
        elif f"SUJ/{arm}" not in self.arms:
            result = (np.eye(4), f"{arm}_base")
        elif kin_type == "ECM":
            result = (self._T_cart_rcm("ECM"), "Cart")
        elif "ECM" in self.arms and "SUJ/ECM" in self.arms:
            result = (invert_transform(self.T_cart_camera()) @ self._T_cart_rcm(arm), "ECM")
        else:
            result = (self._T_cart_rcm(arm), "Cart")
        return result

    def _compute_camera_frame(self, _key: str) -> np.ndarray:
        ecm = self.arms["ECM"]
        return self.default_base_frame("ECM")[0] @ fk.forward_kinematics(
            ecm.chain, ecm.measured_jp()
        )

    # ------------------------------------------------------------ sensors
    def contact_force(self, arm: str) -> np.ndarray:
        """Contact force (N, cart/world frame) on the instrument of ``arm`` (PSM) or the scope."""
        if arm not in self._instrument_bodies:
            raise KeyError(
                f"no instrument on {arm!r}; arms with one: {list(self._instrument_bodies)}"
            )
        return contact_force(self.model, self.data, self._instrument_bodies[arm])

    def camera_names(self) -> list[str]:
        return [self.model.camera(i).name for i in range(self.model.ncam)]

    def render(
        self, camera: str, width: int = 640, height: int = 480, *, fast: bool = False
    ) -> np.ndarray:
        """RGB image from a named camera (``ECM/left``, ``ECM/right``, ``overview`` …).

        ``fast``: no shadows and no anti-aliasing (see :class:`CameraRenderer`).
        """
        if self._cameras is None:
            self._cameras = CameraRenderer(self.model)
        return self._cameras.render(self.data, camera, width, height, fast=fast)

    def render_stereo(
        self, width: int | None = None, height: int | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Left and right endoscope images (default size: the scene's endoscope config)."""
        width = width or self.endoscope.width
        height = height or self.endoscope.height
        return (
            self.render("ECM/left", width, height, fast=True),
            self.render("ECM/right", width, height, fast=True),
        )

    def close(self) -> None:
        if self._cameras is not None:
            self._cameras.close()
            self._cameras = None
