"""The simulated MTML/MTMR of the console model as a master device.

The device reads the MTM arm of the simulation (``measured_cp`` in HRSV, ``measured_cv``,
``gripper/measured_js``) and renders wrenches with ``spatial/servo_cf``. The operator is
simulated too: a *hand* that holds the handle and pulls it towards a target pose through a
spring-damper (:mod:`davinci_sim.devices.hand`), or pushes it with a given wrench, applied to
the handle body as an external force (MuJoCo ``xfrc_applied``); the fingers set the gripper.
Synthetic trainees, tests and the web console move the MTM this way, and the MTM answers
with its own dynamics, the teleoperation's effort modes and the haptic wrench.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np

from davinci_sim.devices.device import MasterDevice
from davinci_sim.devices.hand import HandImpedance, hand_wrenches, handle_xfrc
from davinci_sim.devices.safety import WrenchLimits
from davinci_sim.devices.state import DeviceInput
from davinci_sim.kinematics import jit
from davinci_sim.sim.arms import MTM
from davinci_sim.sim.types import ACCEPTED, CommandResult
from davinci_sim.sim.validation import MAX_FORCE, MAX_TORQUE, as_transform

if TYPE_CHECKING:
    from davinci_sim.sim.simulation import Simulation

_ROW = None  # the read's compiled row (devices/device_row.py), when numba compiles it
if jit.ENABLED:
    from davinci_sim.devices import device_row as _row_module

    if jit.warmed_up(_row_module._warm_up, "the simulated MTM's compiled read: Python runs"):
        _ROW = _row_module

_NO_TARGET = np.eye(4)  # (the compiled read's target argument when the hand has none)

#: The body the hand holds: the last gimbal link, which carries the handle (model/mtm.py).
HANDLE_BODY = "wrist_roll"


class SimulatedMTM(MasterDevice):
    """The MTM ``mtm`` of ``sim`` as a master device, with a simulated hand.

    Args:
        sim: the simulation.
        mtm: ``"MTML"`` or ``"MTMR"``.
        name: component name (default ``"<mtm>/device"``).
        limits: safety limits on rendered wrenches.
        hand: the simulated hand's impedance.
    """

    kind = "simulated"
    can_align = True
    is_haptic = True

    def __init__(
        self,
        sim: Simulation,
        mtm: str = "MTMR",
        *,
        name: str | None = None,
        limits: WrenchLimits | None = None,
        hand: HandImpedance | None = None,
    ) -> None:
        arm = sim.arms.get(mtm)
        if not isinstance(arm, MTM):
            mtms = [n for n, a in sim.arms.items() if isinstance(a, MTM)]
            raise KeyError(f"no MTM {mtm!r} in this simulation; MTMs: {mtms}")
        super().__init__(name or f"{mtm}/device", limits=limits, dt=sim.dt)
        self.sim = sim
        self.arm = arm
        self.mtm = mtm
        self.hand = hand or HandImpedance()
        model, data = sim.model, sim.data
        self._body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"{mtm}/{HANDLE_BODY}")
        if self._body < 0:
            raise KeyError(f"the model has no body {mtm}/{HANDLE_BODY!r} for the hand")
        self._hand_body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"{mtm}/hand")
        hrsv = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "console/HRSV")
        # HRSV is fixed to the console: its world pose from the initial forward pass.
        self._R_world_hrsv = data.xmat[hrsv].reshape(3, 3).copy()
        self._p_world_hrsv = data.xpos[hrsv].copy()
        self._hand_target: np.ndarray | None = None
        # The target's velocity over this tick (HRSV: m/s, then rad/s), as its mover says:
        # the hand's damping acts on the handle's motion relative to it (move_hand).
        self._hand_velocity = np.zeros(6)
        self._hand_on = False
        self._hold_orientation = True
        self._push = np.zeros(6)
        self._hand_wrench = np.zeros(6)
        self._hand_applied = False
        self._row_impedance: tuple[np.ndarray, HandImpedance] | None = None  # (_read_compiled)
        self._steps: tuple[WrenchLimits, float, np.ndarray] | None = None  # (_render_steps)

    # ------------------------------------------------------------ model
    @property
    def handle_body(self) -> int:
        """Id of the body the hand pushes (``<MTM>/wrist_roll``)."""
        return self._body

    @property
    def hand_body(self) -> int:
        """Id of the hand's body at the MTM tip (its mass is the hand's while it holds)."""
        return self._hand_body

    @property
    def T_world_hrsv(self) -> np.ndarray:
        """The console's HRSV frame in the world, 4x4 (fixed)."""
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = self._R_world_hrsv, self._p_world_hrsv
        return T

    # ------------------------------------------------------------ the operator's hand
    def _hold(self, holding: bool) -> None:
        """While the hand holds the handle, the model's hand body (``<MTM>/hand``, at the
        grip, weight compensated) has the hand's mass (``hand.mass``)."""
        self._hand_on = holding
        if self._hand_body >= 0:
            self.sim.model.body_mass[self._hand_body] = self.hand.mass if holding else 0.0

    def grasp(self, target=None, *, hold_orientation: bool = True) -> None:
        """The hand takes the handle and pulls it to ``target``.

        Args:
            target: a 4x4 pose in HRSV, a position (3,) in HRSV (the orientation target is
                the handle's current orientation), or None for where the handle is now.
            hold_orientation: False leaves the wrist relaxed (no torque towards a target
                orientation; e.g. while the MTM aligns itself).

        Raises:
            ValueError: for a target that is not a proper pose or a finite position.
        """
        self._hand_target = self._as_target(target)
        self._hand_velocity[:] = 0.0
        self._hold_orientation = bool(hold_orientation)
        self._hold(True)

    def move_hand(self, target, velocity=None) -> None:
        """Move the hand's target: a 4x4 pose, or a position (3,) keeping the target
        orientation. Grasps the handle if the hand was off.

        ``velocity`` (6,): how fast the target itself moves over this tick (HRSV: m/s, then
        rad/s; a rate input's hand moving at its key's speed). The hand's damping then acts
        on the handle's motion relative to the hand, ``D·(v_target − v)``, as a limb's
        impedance acts about its own planned motion, so a handle moved with the hand is not
        held back by it (about 25 ms of lag behind a key at the default impedance). It holds
        for the next read only: a mover sets it every tick it moves. None: a target at
        rest, ``−D·v``.

        Raises:
            ValueError: for a target that is not a proper pose or a finite position, or a
                velocity that is not 6 finite numbers (nothing changed).
        """
        T = self._as_target(target, keep_orientation=True)
        if velocity is not None:
            v = np.asarray(velocity, dtype=float)
            if v.shape != (6,) or not np.isfinite(v).all():
                raise ValueError(f"hand velocity must be 6 finite numbers, got {velocity!r}")
            self._hand_velocity[:] = v
        else:
            self._hand_velocity[:] = 0.0
        self._hand_target = T
        self._hold(True)

    def release(self) -> None:
        """The hand lets go of the handle (pushes stop too)."""
        self._hold(False)
        self._hand_target = None
        self._hand_velocity[:] = 0.0
        self._push = np.zeros(6)
        self._hand_wrench = np.zeros(6)
        self._hand_applied = False
        self.sim.data.xfrc_applied[self._body] = 0.0

    def push(self, wrench) -> None:
        """An extra constant wrench the hand applies at the tip: force (N) [then torque
        (N·m)] in HRSV axes, shape (3,) or (6,); zeros to stop pushing."""
        w = np.asarray(wrench, dtype=float)
        if w.shape == (3,):
            w = np.concatenate([w, np.zeros(3)])
        if w.shape != (6,) or not np.isfinite(w).all():
            raise ValueError(f"push needs 3 or 6 finite numbers (N, N·m), got {wrench!r}")
        self._push = np.array(w, dtype=float)  # (own, writable: the compiled read's argument)

    def squeeze(self, angle: float) -> CommandResult:
        """The fingers set the gripper opening, rad (−15° squeezed, 0 just closed … 60°;
        dvrk.md 1.5, 4.1)."""
        return self.arm.gripper.servo_jp(angle)

    def hand_target(self) -> np.ndarray | None:
        """The hand's target pose in HRSV (None when the hand is off)."""
        return None if self._hand_target is None else self._hand_target.copy()

    def hand_wrench(self) -> np.ndarray:
        """The wrench the hand applied at the last tick (HRSV axes)."""
        return self._hand_wrench.copy()

    def _as_target(self, target, keep_orientation: bool = False) -> np.ndarray:
        if target is None:
            return self.arm.measured_cp().T.copy()
        arr = np.asarray(target, dtype=float)
        if arr.shape == (3,):
            if not np.isfinite(arr).all():
                raise ValueError(f"hand target position must be finite, got {target!r}")
            if keep_orientation and self._hand_target is not None:
                T = self._hand_target.copy()
            else:
                T = self.arm.measured_cp().T.copy()
            T[:3, 3] = arr
            return T
        T, msg = as_transform(arr, "hand target")
        if T is None:
            raise ValueError(msg)
        return T.copy()

    # ------------------------------------------------------------ MasterDevice
    def _read(self, t: float) -> DeviceInput:
        arm = self.arm
        T = arm._measured_T()  # (measured_cp().T and measured_cv().twist, read-only)
        if _ROW is not None:
            return self._read_compiled(T, t)
        twist = arm._measured_twist()
        if self._hand_on or self._pushing or self._hand_applied:
            w = self._push.copy()
            if self._hand_on:
                hand = self.hand
                target = None if self._hand_target is None else self._hand_target[None]
                w += hand_wrenches(
                    target,
                    T[None],
                    (twist - self._hand_velocity)[None],  # (relative to the hand's motion)
                    (hand.stiffness,),
                    (hand.damping,),
                    hand,
                    hold_orientation=self._hold_orientation,
                )[0]
            self._apply_hand(w, T)
        self._hand_velocity[:] = 0.0  # (this tick's: used)
        return DeviceInput(T, twist, arm.gripper.measured_jp(), t)

    def _read_compiled(self, T: np.ndarray, t: float) -> DeviceInput:
        """:meth:`_read` after the pose in one compiled call (``device_row.hand_read_row``):
        the same laws and the same bits."""
        arm, hand = self.arm, self.hand
        J = arm._measured_kinematics(jacobian=True)[2]
        twist, w, xfrc = np.empty(6), np.empty(6), np.empty(6)
        target = self._hand_target
        impedance = self._row_impedance
        if impedance is None or impedance[1] is not hand:  # (the hand may be replaced)
            impedance = self._row_impedance = (
                np.array([hand.stiffness, hand.damping, hand.rotational_stiffness,
                          hand.rotational_damping, hand.max_force, hand.max_torque]),
                hand,
            )  # fmt: skip
        body = self._body
        data = self.sim.data
        if _ROW.hand_read_row(
            T, arm.base_frame()[0][:3, :3], J, arm._qd(), self._hand_on,
            _NO_TARGET if target is None else target, self._hand_velocity, target is not None,
            self._hold_orientation, self._hand_applied, impedance[0], self._push,
            self._R_world_hrsv, self._p_world_hrsv, data.xipos[body], twist, w, xfrc,
        ):  # fmt: skip
            self._hand_wrench = w
            self._hand_applied = bool(w.any())
            data.xfrc_applied[body] = xfrc
        twist.setflags(write=False)
        return DeviceInput(T, twist, arm.gripper.measured_jp(), t)

    @property
    def _pushing(self) -> bool:
        return bool(self._push.any())

    def _apply_hand(self, w: np.ndarray, T_hrsv_tip: np.ndarray) -> None:
        self._hand_wrench = w
        self._hand_applied = bool(w.any())
        data = self.sim.data
        data.xfrc_applied[self._body] = handle_xfrc(
            w, T_hrsv_tip[:3, 3], self._R_world_hrsv, self._p_world_hrsv, data.xipos[self._body]
        )

    def is_ready(self) -> bool:
        state = self.arm.operating_state()
        return state.state == "ENABLED" and state.is_homed

    def not_ready_reason(self) -> str:
        state = self.arm.operating_state()
        if state.state != "ENABLED":
            return f"{self.mtm} is {state.state}"
        if not state.is_homed:
            return f"{self.mtm} is not homed"
        return ""

    def prepare(self) -> None:
        state = self.arm.operating_state()
        if state.state != "ENABLED":
            self.arm.state_command("enable")
        if not state.is_homed and not self.arm.is_busy():
            self.arm.state_command("home")

    def is_busy(self) -> bool:
        return self.arm.is_busy()

    def move_cp(self, T_hrsv_tip) -> CommandResult:
        result = self.arm.move_cp(T_hrsv_tip)
        if result:
            self._wrench_dropped()  # position control now
        return result

    def hold(self) -> None:
        if self.arm.operating_state().state == "ENABLED":
            self.arm.hold()
        self._wrench_dropped()

    def enter_effort_mode(self) -> None:
        self.arm.use_gravity_compensation(True)
        super().enter_effort_mode()

    def lock_orientation(self, R_hrsv_tip) -> None:
        self.arm.lock_orientation(R_hrsv_tip)

    def unlock_orientation(self) -> None:
        self.arm.unlock_orientation()

    def wrench(self) -> np.ndarray:
        """The wrench the MTM renders now (zero unless in ``spatial/servo_cf`` mode)."""
        current = self.arm.wrench_setpoint()
        return current[1] if current is not None and current[0] == "spatial" else np.zeros(6)

    def _render_wrench(self, w: np.ndarray) -> CommandResult:
        """The device's clamp and ``spatial/servo_cf`` in one compiled call
        (``device_row.render_row``) while the MTM renders wrenches already; else (the first
        wrench, limits beyond the arm's bounds, a stale device, an arm not ready, no numba)
        the Python path. The same bits either way: the wrench let through, the limiter's
        state, the efforts the next step uses. (Between two ticks the Python path may still
        hold the last tick's efforts for a wrench equal to the last one; the arm's pre-step
        recomputes them at the new joints, which this call has done already.)"""
        args = self.render_args()
        if args is None:
            return super()._render_wrench(w)
        q, T_ref_base, J, previous, steps, ftmax = args
        limited, tau = np.empty(6), np.empty(self.arm.dof)
        active = _ROW.render_row(w, previous, steps, T_ref_base, J, ftmax, limited, tau)
        return self.rendered(limited, tau, bool(active), q, T_ref_base)

    def render_args(self) -> tuple | None:
        """What the compiled render of a checked wrench needs now (``device_row.render_row``'s
        inputs: the MTM's joints, base frame in HRSV, spatial Jacobian, the limiter's last
        wrench, the clamp's steps, the joints' effort limits), or None where the Python path
        must render (the first wrench, limits beyond the arm's bounds, a stale device, an arm
        not ready, no numba). A caller that renders with them calls :meth:`rendered`."""
        arm = self.arm
        current = arm._wrench
        if (
            _ROW is None
            or current is None
            or current[0] != "spatial"
            or not self._limits_within_arm()
            or self.is_stale()
            or arm._not_ready()
        ):
            return None
        q, _, J = arm._measured_kinematics()
        return (
            q,
            arm.base_frame()[0],
            J,
            self._limiter.previous,
            self._render_steps(),
            arm.chain.ftmax,
        )

    def rendered(self, limited, tau, active: bool, q, T_ref_base) -> CommandResult:
        """Keep a compiled render's result (:meth:`render_args`): the wrench let through
        ``limited`` (6,) and whether the clamp changed it, as the limiter's state and the
        device's wrench; the efforts ``tau`` at the joints ``q`` as the arm's hold."""
        limiter = self._limiter
        limiter.active = active
        limiter.previous = limited
        sent = self._wrench = limited.copy()  # (the device and the arm hold one object)
        self.arm._hold_wrench_effort("spatial", sent, tau, q, T_ref_base)
        return ACCEPTED

    def _limits_within_arm(self) -> bool:
        """Whether the device's limits are within the arm's own wrench bounds (the
        defaults), so that a wrench the device let through needs no check there."""
        limits = self._limiter.limits
        return limits.max_force <= MAX_FORCE and limits.max_torque <= MAX_TORQUE

    def _render_steps(self) -> np.ndarray:
        """The clamp's four numbers for :func:`device_row.render_row`, as
        ``WrenchLimiter.limit_checked`` computes them (cached per limits object)."""
        limiter = self._limiter
        cached = self._steps
        if cached is None or cached[0] is not limiter.limits or cached[1] != limiter.dt:
            limits, dt = limiter.limits, limiter.dt
            steps = np.array([float(limits.max_force), float(limits.max_torque),
                              float(limits.max_force_rate * dt),
                              float(limits.max_torque_rate * dt)])  # fmt: skip
            cached = self._steps = (limits, dt, steps)
        return cached[2]

    def _apply_wrench(self, wrench: np.ndarray) -> None:
        current = self.arm.wrench_setpoint()
        if current is not None and current[0] == "spatial" and np.array_equal(current[1], wrench):
            return  # already applied (the arm re-applies it every tick)
        # The device's wrench is checked and clamped to its limits: within the arm's own
        # bounds when the limits are (the defaults), so not checked again there.
        self.arm._servo_cf("spatial", wrench, checked=self._limits_within_arm())

    # ------------------------------------------------------------ state
    _STATE = MasterDevice._STATE + (
        "hand",
        "_hand_target",
        "_hand_velocity",
        "_hand_on",
        "_hold_orientation",
        "_push",
        "_hand_wrench",
        "_hand_applied",
    )

    def get_state(self) -> dict:
        """The device's state and the mass of the model's hand body (the hand's while it
        holds the handle, :meth:`_hold`)."""
        state = super().get_state()
        if self._hand_body >= 0:
            state["hand_body_mass"] = float(self.sim.model.body_mass[self._hand_body])
        return state

    def set_state(self, state: dict) -> None:
        """Put back a :meth:`get_state`, the hand body's mass in the model included."""
        state = dict(state)
        mass = state.pop("hand_body_mass", None)
        super().set_state(state)
        if mass is not None:
            self.sim.model.body_mass[self._hand_body] = mass
