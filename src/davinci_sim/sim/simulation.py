"""The simulation: a MuJoCo model of the da Vinci system stepped at 1 kHz with dVRK arms.

Each :meth:`Simulation.tick` runs: components' ``pre_step`` (console, teleoperation …) → arm
setpoints (trajectories, wrench-to-effort) → joint servo (PD + gravity compensation) → one
``mj_step`` of 1 ms → components' ``post_step`` (haptic force fields …). Arms read their state
from MuJoCo on demand, so a tick costs only what the physics and the active setpoints need.

Components are registered with :meth:`Simulation.add_component` (the contract and the tick
order: :mod:`davinci_sim.sim.component`). :meth:`Simulation.get_state` /
:meth:`Simulation.set_state` save and restore everything that changes while ticking, and
:meth:`Simulation.reset` returns to the start (:mod:`davinci_sim.sim.state`).
:meth:`Simulation.advance` runs ticks through a chunker's compiled calls where one is set
(the console's, :mod:`davinci_sim.console.chunk`), the same ticks bit for bit.

Size: over 500 lines because :class:`Simulation` is the one face of the simulation (ticks and
their chunks, the setup-joint frames, sensors, components, state); each part delegates to its
own module, and splitting the class would scatter its small methods.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable, Mapping
from types import MappingProxyType

import mujoco
import numpy as np

from davinci_sim.kinematics import fk
from davinci_sim.kinematics.arms import load_arm, load_suj
from davinci_sim.kinematics.suj import T_cart_rcm, frame_plan, frames_into
from davinci_sim.model import build_spec, resolve_scene
from davinci_sim.sim import timers
from davinci_sim.sim.arm import Arm
from davinci_sim.sim.arms import ECM, MTM, PSM, SUJArm
from davinci_sim.sim.component import Component, check_component
from davinci_sim.sim.divergence import DivergenceGuard, arm_owners
from davinci_sim.sim.sensors import CameraRenderer, contact_force, instruments
from davinci_sim.sim.servo import JointServo
from davinci_sim.sim.state import (
    STATE_SPEC,
    SimState,
    Unavailable,
    component_states,
    describe_scene,
    model_signature,
)
from davinci_sim.sim.tracking_watch import TrackingWatch

ARM_NAMES = ("PSM1", "PSM2", "PSM3", "ECM", "MTML", "MTMR")
#: The base frames and the camera frame are memoized on the exact values of the setup and
#: ECM joints and recomputed when any of them changes at all: the setup joints yield a little
#: under the arms' reaction forces, and a frame held within 1e-6 put ``measured_cp`` µm off
#: the model. A tolerance > 0 (rad or m) holds the frames while the joints stay that close:
#: only to compare with the study's batch engine, which holds them; 0, the default, is exact.
BASE_FRAME_TOLERANCE = 0.0
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
        timers.quiet()  # (MuJoCo's stage timers: nothing here reads them; sim/timers.py)
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
        self._base_frames: dict[str, tuple[bytes, dict]] = {}
        self.arms: dict[str, Arm] = {}
        for name in ARM_NAMES:
            kin = load_arm(name)
            if _has_joint(self.model, f"{name}/{kin.chain.joint_names[0]}"):
                self.arms[name] = _ARM_CLASSES[kin.arm_type](name, kin, self)
        for name, suj in self._suj.items():
            if _has_joint(self.model, f"SUJ/{name}/{suj.chain.joint_names[0]}"):
                self.arms[f"SUJ/{name}"] = SUJArm(f"SUJ/{name}", suj, self)
        self._init_frames()
        self._watch = TrackingWatch(list(self.arms.values()))
        # Fingers (PSM jaws, MTM grippers) hold their initial opening.
        self.servo.q_ref[:] = self.data.qpos[self.servo.qposadr]
        kinds = {name: arm.kin.arm_type for name, arm in self.arms.items()}
        self._instruments = instruments(self.model, kinds)  # (bodies, geoms) by arm
        self._cameras: CameraRenderer | None = None
        self._components: dict[str, Component] = {}
        self._guard = DivergenceGuard(self.model, self.data)
        self._owners = arm_owners(self.arms)
        self.keyframe = keyframe
        """The keyframe the simulation was built at (what :meth:`reset` returns to)."""
        # reset(): the simulation as built (physics, arms, servo), the components' states at
        # the first tick (as assembled), and each component added later as it was added.
        self._built = self._capture(strict=True)
        self._initial_components: dict[str, object] | None = None
        self._chunker = None
        self._added_states: dict[str, object] = {}

    # ------------------------------------------------------------ time
    @property
    def time(self) -> float:
        """Simulation time in s."""
        return float(self.data.time)

    def tick(self) -> None:
        """One 1 ms tick: components → arm setpoints → watch → servo → physics → components."""
        if self._chunker is not None:  # (its deferred write-back first: the tick reads it)
            self.flush()
        if self._initial_components is None:  # the components as assembled: for reset()
            self._initial_components = dict(self._capture_components(strict=False))
        t = self.data.time
        for component in self._components.values():
            component.pre_step(t)
        for arm in self.arms.values():
            arm._pre_step(t)
        self._watch.check(self.measured_qpos(), self.servo, t)
        self.servo.apply(self.data)
        self._guard.save(self.data)
        mujoco.mj_step(self.model, self.data)
        if tripped := self._guard.tripped():
            self._recover(tripped)
        self.tick_count += 1
        if self.encoder_noise_std > 0:
            noise = self.rng.normal(0.0, self.encoder_noise_std, self.data.qpos.shape)
            self._noisy_qpos = self.data.qpos + noise
        self._post_steps()

    def _post_steps(self) -> None:
        """The components' post-steps of the tick whose step just ran."""
        t = self.data.time
        for component in self._components.values():
            if (post_step := getattr(component, "post_step", None)) is not None:
                post_step(t)

    def _recover(self, tripped: dict[str, int]) -> None:
        """Undo a step MuJoCo found unstable: the physics back to before it (the clock advances),
        the arms involved stopped and in FAULT, the rest ticking on (sim/divergence.py)."""
        arms, reason = self._guard.recover(self.data, self._owners, tripped)
        for name in arms:
            self.arms[name]._fault(reason)

    @property
    def recoveries(self) -> int:
        """How many diverged physics steps were undone (see :meth:`_recover`)."""
        return self._guard.recoveries

    def step(self, n: int = 1) -> None:
        """``n`` ticks (:meth:`advance`)."""
        self.advance(n)

    def advance(self, n: int, *, unchanged: bool = False, defer: bool = False) -> None:
        """``n`` ticks: in the chunker's compiled calls where it has them (a console in its
        steady state, :mod:`davinci_sim.console.chunk`: the same ticks, bit for bit), else
        one :meth:`tick` at a time. ``unchanged``: nothing has touched the simulation since
        the last ``advance`` (the live runners know: no call served in between). ``defer``:
        the chunker may leave what its calls write back into the components (their reads,
        the task session's samples, its events) until :meth:`flush`, which the next tick,
        a changed ``advance``, a served call and the state's capture run first: the live
        runners defer between the ends of their snapshot periods, where nothing but the
        kernel reads the components."""
        done, changed = 0, not unchanged
        while done < n:
            chunker = self._chunker
            if chunker is not None:
                if defer:
                    ran, post = chunker(n - done, changed, defer=True)
                else:
                    ran, post = chunker(n - done, changed)
                done += ran
                changed = post or not ran
                if post:  # (the next tick's step ran: its post-steps are Python's)
                    self._post_steps()
                    done += 1
                if ran or post or done >= n:
                    continue
            self.tick()
            done += 1
            changed = True

    @property
    def chunker(self):
        """What runs :meth:`advance`'s ticks in compiled calls, or None (see
        :meth:`set_chunker`)."""
        return self._chunker

    def set_chunker(self, chunker) -> None:
        """Run :meth:`advance`'s ticks through ``chunker`` (``chunker(n, changed) ->
        (ticks, post)``: at most n ticks run whole, and whether the next one's step ran too,
        its post-steps left to the caller; ``changed`` False when nothing but its own calls
        ran since its last one; with ``defer=True`` (:meth:`advance`'s) it may leave its
        write-back to its ``flush()``), or None: every tick in Python."""
        self.flush()
        self._chunker = chunker

    def flush(self) -> None:
        """What the chunker's deferred calls (``advance(defer=True)``) left to write back,
        written back now: the components as the ticks left them, the task session's samples
        taken, its events emitted. A no-op when nothing waits."""
        flush = getattr(self._chunker, "flush", None)
        if flush is not None:
            flush()

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
    def _init_frames(self) -> None:
        """The SUJ frame kernel's plan for the setup-joint arms present (dvrk.md 1.6)."""
        self._frame_plan = None
        self._frame_adr = np.zeros(0, dtype=int)
        if "ECM" in self.arms and "SUJ/ECM" in self.arms:
            suj = {n: s for n, s in self._suj.items() if f"SUJ/{n}" in self.arms}
            self._frame_plan = frame_plan(suj, self.arms["ECM"].chain, "ECM")
            parts = [self.arms[f"SUJ/{n}"]._qposadr for n in self._frame_plan.arms]
            self._frame_adr = np.concatenate([*parts, self.arms["ECM"]._qposadr])

    def _frames(self) -> dict:
        """The base frames (by arm) and ``camera`` at the joints now: recomputed when a setup
        or ECM joint changed (:data:`BASE_FRAME_TOLERANCE`), else the same objects."""
        q = self.measured_qpos()[self._frame_adr]
        key = q.tobytes()
        entry, tol = self._base_frames.get("frames"), BASE_FRAME_TOLERANCE
        if entry is not None and (
            entry[0] == key or (tol > 0 and np.abs(q - np.frombuffer(entry[0])).max() <= tol)
        ):
            return entry[1]
        plan = self._frame_plan
        return self._keep_frames(key, frames_into(plan, q[: -plan.dof], q[-plan.dof :]))

    def _keep_frames(self, key: bytes, out: np.ndarray) -> dict:
        """:meth:`_frames`' answer for the joints ``key`` from ``out`` (frames_into's rows)."""
        out.setflags(write=False)
        plan, k = self._frame_plan, len(self._frame_plan.arms)
        frames = {"camera": out[k]}
        for i, name in enumerate(plan.arms):
            frames[name] = (out[k + 2 + i], "Cart" if i == plan.reference else "ECM")
        self._base_frames["frames"] = (key, frames)
        return frames

    def default_base_frame(self, arm: str) -> tuple[np.ndarray, str]:
        """Base frame of ``arm`` as the dVRK system computes it (dvrk.md 1.6, 1.5), from the
        joints as they are now (exactly: see :data:`BASE_FRAME_TOLERANCE`).

        PSM: its RCM in the ECM tip (camera) frame, reference ``ECM``; ECM: its RCM in the
        cart, reference ``Cart``; MTM: its base in ``HRSV``; SUJ arm: its base in the cart.
        """
        kin_type = self.arms[arm].kin.arm_type
        if kin_type == "MTM":
            return self.arms[arm].kin.T_reference_base, "HRSV"
        if kin_type == "SUJ":
            return self._suj[arm.split("/", 1)[1]].T_cart_sujbase, "Cart"
        if f"SUJ/{arm}" not in self.arms:
            return np.eye(4), f"{arm}_base"
        if self._frame_plan is not None:
            return self._frames()[arm]
        # A PSM on its setup joints without an ECM on its own: its RCM in the cart.
        return T_cart_rcm(self._suj[arm], self.arms[f"SUJ/{arm}"].measured_jp()), "Cart"

    def T_cart_camera(self) -> np.ndarray:
        """The ECM tip (camera frame) in the cart (world) frame, 4x4, m (dvrk.md 1.6)."""
        if "ECM" not in self.arms:
            raise KeyError("no ECM in this simulation: there is no camera frame")
        if self._frame_plan is not None:
            return self._frames()["camera"]
        ecm = self.arms["ECM"]
        return self.default_base_frame("ECM")[0] @ fk.forward_kinematics(
            ecm.chain, ecm.measured_jp()
        )

    # ------------------------------------------------------------ sensors
    def contact_force(self, arm: str) -> np.ndarray:
        """Contact force (N, cart/world frame) on the instrument of ``arm`` (PSM) or the scope."""
        if arm not in self._instruments:
            raise KeyError(f"no instrument on {arm!r}; arms with one: {list(self._instruments)}")
        return contact_force(self.model, self.data, *self._instruments[arm])

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

    # ------------------------------------------------------------ components
    @property
    def components(self) -> Mapping[str, Component]:
        """The components (console, devices, teleops …) by name, in tick order (read-only:
        :meth:`add_component`, :meth:`remove_component`); see :mod:`davinci_sim.sim.component`."""
        return MappingProxyType(self._components)

    def add_component(
        self, component: Component, *, before: str | None = None, after: str | None = None
    ) -> None:
        """Tick ``component`` with the arms: just before the component named ``before``, just
        after the one named ``after``, or (neither) after all the others.

        Raises:
            TypeError: if it lacks ``name``, ``pre_step`` or ``snapshot``.
            ValueError: if its name is taken, or both ``before`` and ``after`` are given.
            KeyError: if ``before``/``after`` names no component.
        """
        check_component(component)
        self.flush()  # (the components as the ticks left them, before the set changes)
        name = component.name
        if name in self._components:
            raise ValueError(
                f"a component named {name!r} is already registered; components: "
                f"{list(self._components)}"
            )
        if before is not None and after is not None:
            raise ValueError(f"add_component({name!r}): give before= or after=, not both")
        anchor = before if before is not None else after
        if anchor is not None and anchor not in self._components:
            raise KeyError(
                f"add_component({name!r}): no component {anchor!r} to go "
                f"{'before' if before is not None else 'after'}; components: "
                f"{list(self._components)}"
            )
        items = list(self._components.items())
        at = len(items)
        if anchor is not None:
            at = [n for n, _ in items].index(anchor) + (0 if before is not None else 1)
        items.insert(at, (name, component))
        self._components.clear()
        self._components.update(items)
        if self._initial_components is not None and callable(getattr(component, "get_state", None)):
            self._added_states[name] = component.get_state()  # what reset() returns it to

    def remove_component(self, name: str) -> Component:
        """Stop ticking the component ``name``; returns it.

        Raises:
            KeyError: if there is none of that name.
        """
        if name not in self._components:
            raise KeyError(f"no component {name!r}; components: {list(self._components)}")
        self.flush()
        self._added_states.pop(name, None)
        return self._components.pop(name)

    # ------------------------------------------------------------ state
    def get_state(self) -> SimState:
        """Everything that changes while the simulation ticks (:mod:`davinci_sim.sim.state`):
        :meth:`set_state` with it resumes bit-identically.

        Raises:
            TypeError: if a component has no ``get_state``.
        """
        self.flush()
        return self._capture(strict=True)

    def set_state(self, state: SimState) -> None:
        """Put the simulation back in ``state`` (from :meth:`get_state` of this simulation or
        of one of the same scene with the same components): physics, arms, servo, time, tick
        count, random generator and every component. Nothing is emitted on the channels.
        If a component refuses its state, the simulation is left as it was.

        Raises:
            TypeError: if ``state`` is not a :class:`SimState` or a component cannot
                restore.
            ValueError: for a state of another scene or of other components.
        """
        self.flush()  # (the ticks before it completed: their write-back must not follow it)
        if not isinstance(state, SimState):
            raise TypeError(f"set_state needs a SimState, got {type(state).__name__}")
        if state.signature != self.signature:
            raise ValueError(
                "this state belongs to another scene (model signature "
                f"{state.signature[:12]} != {self.signature[:12]}); this simulation: "
                f"{describe_scene(self.model)}, the state's: "
                f"{describe_scene(state.data.model)}"
            )
        names = [name for name, _ in state.components]
        if names != list(self._components):
            raise ValueError(
                f"the state's components {names} are not this simulation's "
                f"{list(self._components)} (same names in the same tick order needed)"
            )
        for name, component_state in state.components:
            component = self._components[name]
            if not callable(getattr(component, "set_state", None)):
                raise TypeError(f"component {name!r} ({type(component).__name__}) has no set_state")
            if isinstance(component_state, Unavailable):
                raise TypeError(f"no state of component {name!r}: {component_state.reason}")
        if not state.components:  # (nothing that can refuse: no backup to take)
            self._restore(state)
            return
        backup = self._capture(strict=False)
        try:
            self._restore(state)
        except Exception:  # a component refused (e.g. other force fields): nothing changes
            self._restore(backup)
            raise

    def _restore(self, state: SimState) -> None:
        mujoco.mj_copyData(self.data, self.model, state.data)
        self._guard.sync()  # the copied warning counts are the baseline
        self.tick_count = state.tick_count
        self.rng.bit_generator.state = copy.deepcopy(state.rng)
        self._noisy_qpos = None if state.noisy_qpos is None else state.noisy_qpos.copy()
        self.servo.set_state(state.servo)
        self._base_frames = copy.deepcopy(state.base_frames)
        for name, arm in self.arms.items():
            arm.set_state(state.arms[name])
        for name, component_state in state.components:
            if not isinstance(component_state, Unavailable):
                self._components[name].set_state(component_state)

    def reset(self, keyframe: str | None = None) -> None:
        """Back to the start: the physics, arms and servo as the simulation was built, every
        component as it was at the first tick (as assembled: e.g. a console installed with
        the operator present), components added later as they were when added; then, for a
        ``keyframe`` other than the one it was built at (:attr:`keyframe`), MuJoCo's keyframe
        with every joint's setpoint where the joint is (as a new simulation starts).

        Raises:
            ValueError: for an unknown keyframe.
            TypeError: if a component cannot save or restore its state.
        """
        self.flush()
        key = -1
        if keyframe is not None and keyframe != self.keyframe:
            key = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_KEY, keyframe)
            if key < 0:
                names = [self.model.key(i).name for i in range(self.model.nkey)]
                raise ValueError(f"unknown keyframe {keyframe!r}; keyframes: {names}")
        initial = self._initial_components
        if initial is None:  # never ticked: the components' states now are the initial ones
            initial = self._initial_components = dict(self._capture_components(strict=False))
        components = []
        for name in self._components:
            if name in self._added_states:
                components.append((name, self._added_states[name]))
            elif name in initial:
                components.append((name, initial[name]))
            else:
                raise TypeError(f"component {name!r} has no initial state (no get_state)")
        self.set_state(dataclasses.replace(self._built, components=tuple(components)))
        if key >= 0:
            mujoco.mj_resetDataKeyframe(self.model, self.data, key)
            self._guard.sync()
            mujoco.mj_forward(self.model, self.data)
            self.servo.q_ref[:] = self.data.qpos[self.servo.qposadr]
            self.servo.qd_ref[:] = 0.0
            self._base_frames.clear()
            for arm in self.arms.values():
                arm.set_state(arm.get_state())  # drops the arm's caches of the old pose

    @property
    def signature(self) -> str:
        """The compiled model's signature (:func:`~davinci_sim.sim.state.model_signature`)."""
        sig = getattr(self, "_signature", None)
        if sig is None:
            sig = self._signature = model_signature(self.model)
        return sig

    @property
    def encoder_noise_sample(self) -> np.ndarray | None:
        """The joint positions the encoders read at the last tick (``qpos`` plus noise), or
        None without encoder noise (then :meth:`measured_qpos` is ``data.qpos``)."""
        return self._noisy_qpos

    def set_encoder_reading(self, qpos: np.ndarray | None) -> None:
        """Set what :meth:`measured_qpos` returns until the next tick (None: the true
        ``qpos``): for a mirror simulation that shows another one's published state."""
        self._noisy_qpos = None if qpos is None else np.asarray(qpos, dtype=float)

    def _capture(self, *, strict: bool) -> SimState:
        physics = np.empty(mujoco.mj_stateSize(self.model, STATE_SPEC))
        mujoco.mj_getState(self.model, self.data, physics, STATE_SPEC)
        physics.setflags(write=False)
        return SimState(
            signature=self.signature,
            physics=physics,
            data=copy.copy(self.data),
            tick_count=self.tick_count,
            rng=copy.deepcopy(self.rng.bit_generator.state),
            noisy_qpos=None if self._noisy_qpos is None else self._noisy_qpos.copy(),
            servo=self.servo.get_state(),
            base_frames=copy.deepcopy(self._base_frames),
            arms={name: arm.get_state() for name, arm in self.arms.items()},
            components=self._capture_components(strict=strict),
        )

    def _capture_components(self, *, strict: bool) -> tuple:
        return component_states(self._components, strict=strict)
