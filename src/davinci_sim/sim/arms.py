"""The arm types of the simulation: PSM, ECM, MTM and the setup-joint arms."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from davinci_sim.geometry import so3
from davinci_sim.kinematics import fk, jit
from davinci_sim.kinematics.arms import ArmKinematics, SUJArmKinematics
from davinci_sim.kinematics.chain import DHChain
from davinci_sim.sim import arm_laws as laws
from davinci_sim.sim.arm import Arm
from davinci_sim.sim.impedance import CartesianImpedance, impedance_problem, impedance_wrench
from davinci_sim.sim.jaw import Jaw
from davinci_sim.sim.trajectory import step_towards
from davinci_sim.sim.types import ACCEPTED, CommandResult
from davinci_sim.sim.validation import MAX_FORCE, MAX_TORQUE, as_number, as_transform, as_twist

if TYPE_CHECKING:
    from davinci_sim.sim.simulation import Simulation

# dvrk.md 1.7: SafeDistanceFromRCM 45 mm minus SafeDistanceFromRCMBuffer 2 mm, measured for
# the frame at the end of the shaft (link 4).
PSM_SAFE_CARTESIAN_DISTANCE = 0.045 - 0.002
# dvrk.md 2.4: the ECM allows Cartesian control once insertion > 50 mm.
ECM_SAFE_CARTESIAN_INSERTION = 0.050

_CP = None  # servo_cp's compiled law (sim/cartesian_kernel.py), when numba compiles it
if jit.ENABLED:
    from davinci_sim.sim import cartesian_kernel as _cp_module

    if jit.warmed_up(_cp_module._warm_up, "servo_cp's compiled law: the Python path runs"):
        _CP = _cp_module


_NO_TWIST = np.zeros(6)


class PSM(Arm):
    """Patient-side manipulator with its instrument's jaw (``psm.jaw``)."""

    def __init__(self, name: str, kin: ArmKinematics, sim: Simulation) -> None:
        super().__init__(name, kin, sim)
        assert kin.jaw is not None
        self.jaw = Jaw(self, kin.jaw, "jaw", kin.jaw_v_max, kin.jaw_a_max)
        self._shaft_chain = self.chain.truncated(4)
        self._shaft_offset = _shaft_offset(self._shaft_chain)
        if _CP is not None:  # servo_cp's compiled law: its constants and output arrays
            self._cp = (_CP.servo_cp_constants(self.chain), np.array(self._feedforward_bound),
                        np.empty(self.dof), np.empty(self.dof))  # fmt: skip

    def shaft_end_distance(self) -> float:
        """Distance (m) from the RCM to the end of the shaft (link-4 frame), dvrk.md 1.7."""
        q = self._sim.measured_qpos()[self._qposadr[:4]]
        if self._shaft_offset is not None:
            # The link-4 origin lies on the shaft axis at insertion + a constant (psm_ik).
            return abs(float(q[2]) + self._shaft_offset)
        f = fk.fk_tuple(self._shaft_chain, q.tolist())
        return math.sqrt(f[9] * f[9] + f[10] * f[10] + f[11] * f[11])

    def _cartesian_unsafe(self) -> str:
        d = self.shaft_end_distance()
        if d < PSM_SAFE_CARTESIAN_DISTANCE:
            return (
                f"tool needs to be inserted past the cannula for Cartesian control: shaft end is "
                f"{1000 * d:.1f} mm from the RCM, needs {1000 * PSM_SAFE_CARTESIAN_DISTANCE:.0f} mm"
            )
        return ""

    def _hold_here(self) -> None:
        super()._hold_here()
        self.jaw._hold()

    def _servo_cp(self, T_goal, twist, checked: bool) -> CommandResult:
        # The common answer through the compiled law; any other (an IK answer to polish or
        # adjust, a singular Jacobian, a refusal and its message) through the Python path.
        if _CP is not None and self._servo_cp_compiled(T_goal, twist, checked):
            return ACCEPTED
        return super()._servo_cp(T_goal, twist, checked)

    def _servo_cp_compiled(self, T_goal, twist, checked: bool) -> bool:
        """:meth:`servo_cp` by :func:`~davinci_sim.sim.cartesian_kernel.servo_cp_row`: True
        when it gave the answer (then applied, as the Python path would), False for the
        Python path to run (nothing changed)."""
        if self._not_ready(cartesian=True):
            return False
        T = T_goal if checked else as_transform(T_goal, "goal")[0]
        tw = None if twist is None else as_twist(twist, "twist")[0]
        if T is None or (twist is not None and tw is None):
            return False
        T = jit.kernel_array(T)  # (the kernel's one signature)
        q, _, J = self._measured_kinematics(jacobian=True)
        constants, bound, q_out, qd_out = self._cp
        feedforward = tw is not None
        if not _CP.servo_cp_row(
            *constants, self._T_base_reference(), T, q, J, feedforward,
            np.array(tw) if feedforward else _NO_TWIST, self._qmin, self._qmax, bound, q_out,
            qd_out,
        ):  # fmt: skip
            return False
        self._servo_position(q_out, qd_out)  # (copied into the servo's references)
        return True

    def _start_homing(self) -> None:
        super()._start_homing()
        self.jaw._start(0.0)  # the jaw is the 7th PID joint and homes with the arm

    def _pre_step(self, t: float) -> None:
        super()._pre_step(t)
        self.jaw._pre_step(t)

    def _pre_step_idle(self) -> bool:
        return super()._pre_step_idle() and self.jaw._traj is None

    def is_busy(self) -> bool:
        return super().is_busy() or self.jaw.is_busy()

    def insert_jp(self, depth: float) -> CommandResult:
        """``move_jp`` with only the insertion joint changed (dvrk_python ``insert_jp``)."""
        return _insert_jp(self, depth)

    def get_state(self) -> dict:
        """The arm's state (:meth:`Arm.get_state`) and the jaw's."""
        return {**super().get_state(), "jaw": self.jaw.get_state()}

    def set_state(self, state: dict) -> None:
        state = dict(state)
        self.jaw.set_state(state.pop("jaw"))
        super().set_state(state)


def _shaft_offset(shaft_chain: DHChain) -> float | None:
    """``c`` with RCM-to-link-4 distance = |q3 + c| for this chain, checked by FK at sample
    joints (None if the chain does not have that structure: FK is used then)."""

    def distance(q) -> float:
        f = fk.fk_tuple(shaft_chain, list(q))
        return math.sqrt(f[9] * f[9] + f[10] * f[10] + f[11] * f[11])

    c = distance((0.0, 0.0, 1.0, 0.0)) - 1.0
    samples = ((0.3, -0.4, 0.05, 1.0), (-0.8, 0.6, 0.12, -2.0), (0.1, 0.2, 0.24, 0.5))
    if all(abs(distance(q) - abs(q[2] + c)) < 1e-12 for q in samples):
        return c
    return None


class ECM(Arm):
    """Endoscope camera manipulator with a straight Classic SD scope (dvrk.md 1.4)."""

    def _cartesian_unsafe(self) -> str:
        ins = self.measured_jp()[2]
        if ins <= ECM_SAFE_CARTESIAN_INSERTION:
            return (
                f"endoscope needs to be inserted past the cannula for Cartesian control: "
                f"insertion {1000 * ins:.1f} mm, "
                f"needs > {1000 * ECM_SAFE_CARTESIAN_INSERTION:.0f} mm"
            )
        return ""

    def insert_jp(self, depth: float) -> CommandResult:
        """``move_jp`` with only the insertion joint changed."""
        return _insert_jp(self, depth)


def _insert_jp(arm: Arm, depth) -> CommandResult:
    d, msg = as_number(depth, "depth")
    if d is None:
        return arm._refuse("insert_jp", msg)
    goal = arm.setpoint_jp()
    goal[2] = d
    return arm.move_jp(goal)


#: MTM joints that orient the handle: wrist platform, pitch, yaw, roll (dvrk.md 1.5). Their
#: axes cross at the tip, so they turn the handle without moving it.
MTM_WRIST_JOINTS = slice(3, 7)
#: The bounds of a servo_cf wrench (sim.validation), for servo_ci's wrench.
_WRENCH_BOUND = np.array([MAX_FORCE] * 3 + [MAX_TORQUE] * 3)
#: Damped-least-squares steps per tick of the orientation lock, and their damping (rad²).
_LOCK_STEPS = 2
_LOCK_DAMPING = 1e-4


class MTM(Arm):
    """Master tool manipulator of the surgeon console, with its gripper (``mtm.gripper``).

    The gripper is an input: on the real console the operator's fingers set it. Here
    ``mtm.gripper.servo_jp`` stands for the fingers (simulation only); ``gripper.measured_js``
    is what the dVRK publishes.

    ``lock_orientation(R)`` (dvrk.md 2.2, MTM-specific) holds the handle's orientation while the
    arm is in effort mode (``free``, ``body/servo_cf``, ``spatial/servo_cf``): the four wrist
    joints are then position-servoed and the three positioning joints stay in effort mode, so
    the hand still moves the handle freely. As on the dVRK, the wrist goes to the locked
    orientation along a trajectory within the MTM's joint limits (dvrk.md 1.9), starting from
    where the wrist is and following the orientation's IK solution as it changes (the handle
    moves, the lock is updated). In position modes the lock is kept but has no effect.
    """

    def __init__(self, name: str, kin: ArmKinematics, sim: Simulation) -> None:
        super().__init__(name, kin, sim)
        assert kin.gripper is not None
        # The fingers are not the arm: they move whatever the arm's state.
        self.gripper = Jaw(self, kin.gripper, "gripper", 4 * np.pi, 8 * np.pi, requires_ready=False)
        self._R_lock: np.ndarray | None = None
        self._wrist_idx = self._idx[MTM_WRIST_JOINTS]
        self._lock_traj: tuple[np.ndarray, np.ndarray] | None = None
        """The wrist's setpoint position and velocity on the way to the locked orientation
        (rad, rad/s); None while the lock does not drive the wrist."""
        self._lock_goal: np.ndarray | None = None
        """The last IK solution of the wrist (rad): the next tick's seed."""
        self._impedance: CartesianImpedance | None = None
        """The ``servo_ci`` gains in force (None: none)."""
        self._impedance_w: np.ndarray | None = None
        self._wrist_limits = (
            self.chain.qmin[MTM_WRIST_JOINTS].copy(),
            self.chain.qmax[MTM_WRIST_JOINTS].copy(),
        )
        assert MTM_WRIST_JOINTS.stop == self.dof  # (the lock's law turns the chain's tail)
        n = self.dof
        self._lock_scratch = fk._consts(self.chain).packed
        self._lock_scratch2 = (np.empty((4, 4)), np.empty((6, n)), np.empty((n, 12)),
                               np.empty((3, 3)), np.empty(3))  # fmt: skip
        self._wrist_v_a = (kin.v_max[MTM_WRIST_JOINTS].copy(), kin.a_max[MTM_WRIST_JOINTS].copy())

    def lock_orientation(self, R_reference_tip) -> CommandResult:
        """Hold the handle at orientation ``R_reference_tip`` (3x3, in the ``measured_cp``
        reference frame, HRSV by default) while in effort mode."""
        R = np.asarray(R_reference_tip, dtype=float) if _is_array_like(R_reference_tip) else None
        if R is None or not so3.is_rotation(R):
            return self._refuse(
                "lock_orientation", f"needs a 3x3 rotation matrix, got {R_reference_tip!r}"
            )
        self._R_lock = R.copy()
        return ACCEPTED

    def servo_ci(self, gains: CartesianImpedance) -> CommandResult:
        """Cartesian impedance (dvrk.md 2.2 ``servo_ci``; :mod:`davinci_sim.sim.impedance`):
        from now on, every tick, the wrench ``gains`` give for the handle's measured pose and
        twist (reference frame, HRSV by default) is applied at the handle, as a
        ``spatial/servo_cf`` would (clamped to its bounds, each joint to its ``ftmax``). Any
        other motion or effort command ends it; the orientation lock works with it. As on the
        dVRK, body wrenches are expressed in the reference orientation from now on
        (``body/set_cf_orientation_absolute(True)``)."""
        why = self._not_ready(cartesian=True)
        if why:
            return self._refuse("servo_ci", why)
        msg = impedance_problem(gains)
        if msg:
            return self._refuse("servo_ci", msg)
        if self._wrench is None or self._wrench[0] != "spatial":  # entering effort mode
            self._set_effort(np.zeros(self.dof))
        self._impedance = gains
        self._body_cf_absolute = True
        self._apply_impedance()
        return ACCEPTED

    def impedance(self) -> CartesianImpedance | None:
        """The ``servo_ci`` gains in force, or None."""
        return self._impedance

    def _apply_impedance(self) -> None:
        """The impedance's wrench at the measured pose and twist, as the spatial wrench."""
        assert self._impedance is not None
        _, T_base_tip, J = self._measured_kinematics(jacobian=True)
        T_ref_base = self.base_frame()[0]
        T_ref_tip = laws.pose_in_reference(T_ref_base, T_base_tip)
        twist = laws.twist_in_reference(T_ref_base[:3, :3], J, self._qd())
        w = np.clip(impedance_wrench(self._impedance, T_ref_tip, twist), -_WRENCH_BOUND,
                    _WRENCH_BOUND)  # fmt: skip
        self._wrench = ("spatial", w)
        self._impedance_w = w  # (another servo_cf replaces it: the impedance ends)
        self._sim.servo.tau_ff[self._idx] = self._wrench_to_effort("spatial", w)

    def unlock_orientation(self) -> CommandResult:
        """Let the handle turn freely again in effort mode."""
        self._R_lock = None
        servo = self._sim.servo
        if self._lock_traj is not None and servo.effort_mode[self._idx[0]]:
            servo.effort_mode[self._wrist_idx] = True  # the wrist back in effort mode
        self._lock_traj = self._lock_goal = None
        return ACCEPTED

    def orientation_locked(self) -> bool:
        return self._R_lock is not None

    def get_state(self) -> dict:
        """The arm's state (:meth:`Arm.get_state`), the gripper's and the orientation lock."""
        return {
            **super().get_state(),
            "gripper": self.gripper.get_state(),
            "R_lock": _copy(self._R_lock),
            "lock_traj": None if self._lock_traj is None else tuple(map(_copy, self._lock_traj)),
            "lock_goal": _copy(self._lock_goal),
            "impedance": self._impedance,  # frozen: shared, not copied
        }

    def set_state(self, state: dict) -> None:
        state = dict(state)
        self.gripper.set_state(state.pop("gripper"))
        self._R_lock = _copy(state.pop("R_lock"))
        lock_traj = state.pop("lock_traj", None)
        self._lock_traj = None if lock_traj is None else tuple(map(_copy, lock_traj))
        self._lock_goal = _copy(state.pop("lock_goal", None))
        self._impedance = state.pop("impedance", None)
        super().set_state(state)
        self._impedance_w = None
        if self._impedance is not None and self._wrench is not None:
            self._impedance_w = self._wrench[1]  # the restored wrench is the impedance's

    def _pre_step_idle(self) -> bool:
        return (
            super()._pre_step_idle() and self._impedance is None and self.gripper._traj is None
            and self._R_lock is None and self._lock_traj is None and self._lock_goal is None
        )  # fmt: skip

    def _pre_step(self, t: float) -> None:
        if self._impedance is not None:
            if (
                self._wrench is None
                or self._wrench[1] is not self._impedance_w
                or (self._state != "ENABLED")
            ):  # another command (or a fault, a disable) ended the impedance
                self._impedance = self._impedance_w = None
            else:
                self._apply_impedance()
        super()._pre_step(t)
        self.gripper._pre_step(t)
        servo = self._sim.servo
        if self._R_lock is None or not servo.effort_mode[self._idx[0]]:
            self._lock_traj = self._lock_goal = None
            return
        if self._lock_traj is None:  # the lock starts driving the wrist: from where it is
            self._lock_traj = (self._q()[MTM_WRIST_JOINTS], self._qd()[MTM_WRIST_JOINTS].copy())
        q, qd = self._lock_step()
        self._lock_traj = (q, qd)
        servo.effort_mode[self._wrist_idx] = False
        servo.q_ref[self._wrist_idx] = q
        servo.qd_ref[self._wrist_idx] = qd

    def _lock_step(self) -> tuple[np.ndarray, np.ndarray]:
        """The wrist's next setpoint ``(q, qd)`` towards the locked orientation: its goal
        (:meth:`_locked_wrist_goal`) and one step of its online trajectory, in one compiled
        call (``arm_laws.wrist_lock_step``, the same bits) or, where the goal's solve
        fails, the Python path's held wrist."""
        assert self._R_lock is not None and self._lock_traj is not None
        r = self._trajectory_ratio
        v_max, a_max = self._wrist_v_a
        q_out, qd_out = np.empty(len(v_max)), np.empty(len(v_max))
        R_base_goal, q = self._lock_seed()
        goal = np.empty(q.shape[0] - MTM_WRIST_JOINTS.start)
        if laws.wrist_lock_step(*self._lock_scratch, q, MTM_WRIST_JOINTS.start, R_base_goal,
                                _LOCK_STEPS, _LOCK_DAMPING, *self._wrist_limits,
                                *self._lock_scratch2, goal, *self._lock_traj, v_max, a_max, r,
                                self._sim.dt, q_out, qd_out):  # fmt: skip
            self._lock_goal = goal
            return q_out, qd_out
        return step_towards(*self._lock_traj, self._locked_wrist_goal(), v_max * r, a_max * r,
                            self._sim.dt)  # fmt: skip

    def _lock_seed(self) -> tuple[np.ndarray, np.ndarray]:
        """The locked orientation in the chain base (3, 3) and the joints seeding its solve
        (a new array: the law updates it)."""
        assert self._R_lock is not None
        R_base_goal = self.base_frame()[0][:3, :3].T @ self._R_lock
        q = self._q()
        if self._lock_goal is not None:  # (the last solution: it leads the measured wrist)
            q[MTM_WRIST_JOINTS] = self._lock_goal
        return R_base_goal, q

    def _locked_wrist_goal(self) -> np.ndarray:
        """Wrist joints giving the locked orientation with the current arm joints
        (:func:`~davinci_sim.sim.arm_laws.locked_wrist_goal`: damped least squares seeded
        with the last solution, so it converges over the ticks as the dVRK's seeded IK)."""
        R_base_goal, q = self._lock_seed()
        goal = np.empty(q.shape[0] - MTM_WRIST_JOINTS.start)
        if not laws.locked_wrist_goal(*self._lock_scratch, q, MTM_WRIST_JOINTS.start,
                                      R_base_goal, _LOCK_STEPS, _LOCK_DAMPING,
                                      *self._wrist_limits, *self._lock_scratch2, goal):  # fmt: skip
            lo, hi = self._wrist_limits  # (no solve: NaN joints) the wrist held where it is
            goal = np.minimum(np.maximum(self._q()[MTM_WRIST_JOINTS], lo), hi)
        self._lock_goal = goal
        return goal


def _copy(a: np.ndarray | None) -> np.ndarray | None:
    return None if a is None else a.copy()


def _is_array_like(value) -> bool:
    try:
        np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return False
    return True


def suj_arm_kinematics(suj: SUJArmKinematics) -> ArmKinematics:
    """SUJ arm as an :class:`ArmKinematics`: the tool is ``SUJ_tip_to_tool_origin`` (dvrk.md 1.6).

    The dVRK moves simulated SUJ joints directly; here they move through dynamics, so
    ``move_jp`` needs limits: 0.1 m/s and 0.5 rad/s, accelerations the same per s (our choice).
    """
    chain = DHChain(suj.chain.name, suj.chain.convention, suj.chain.joints, suj.T_sujtip_rcm)
    n = chain.dof
    v = np.where(chain.revolute, 0.5, 0.1)
    return ArmKinematics(
        arm_type="SUJ",  # type: ignore[arg-type]
        chain=chain,
        home=suj.simulated_position,
        v_max=v,
        a_max=v,
        goal_tolerance=np.full(n, 1e-3),
    )


class SUJArm(Arm):
    """One setup-joint arm (``SUJ/PSM1`` …): ``measured_cp`` is the carried arm's RCM in the cart.

    SUJ arms start ENABLED and homed and ``home`` does not move them: they are passive,
    braked arms on the real system. ``servo_jp``/``move_jp`` move them (simulation only, as
    on the dVRK, dvrk.md 1.6).
    """

    def __init__(self, name: str, suj: SUJArmKinematics, sim: Simulation) -> None:
        super().__init__(name, suj_arm_kinematics(suj), sim)
        self.suj = suj
        self._state = "ENABLED"
        self._homed = True

    def _start_homing(self) -> None:
        # Setup joints are passive and braked: homing them is not a motion.
        self._homed = True
        self._publish_state()
