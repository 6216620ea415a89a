"""The arm types of the simulation: PSM, ECM, MTM and the setup-joint arms."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from scipy.linalg.lapack import dgesv

from davinci_sim.geometry import so3
from davinci_sim.kinematics import fk
from davinci_sim.kinematics.arms import ArmKinematics, SUJArmKinematics
from davinci_sim.kinematics.chain import DHChain
from davinci_sim.sim.arm import Arm
from davinci_sim.sim.jaw import Jaw
from davinci_sim.sim.types import ACCEPTED, CommandResult
from davinci_sim.sim.validation import as_number

if TYPE_CHECKING:
    from davinci_sim.sim.simulation import Simulation

# dvrk.md 1.7: SafeDistanceFromRCM 45 mm minus SafeDistanceFromRCMBuffer 2 mm, measured for
# the frame at the end of the shaft (link 4).
PSM_SAFE_CARTESIAN_DISTANCE = 0.045 - 0.002
# dvrk.md 2.4: the ECM allows Cartesian control once insertion > 50 mm.
ECM_SAFE_CARTESIAN_INSERTION = 0.050


class PSM(Arm):
    """Patient-side manipulator with its instrument's jaw (``psm.jaw``)."""

    def __init__(self, name: str, kin: ArmKinematics, sim: Simulation) -> None:
        super().__init__(name, kin, sim)
        assert kin.jaw is not None
        self.jaw = Jaw(self, kin.jaw, "jaw", kin.jaw_v_max, kin.jaw_a_max)
        self._shaft_chain = self.chain.truncated(4)
        self._shaft_offset = _shaft_offset(self._shaft_chain)

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

    def _start_homing(self) -> None:
        super()._start_homing()
        self.jaw._start(0.0)  # the jaw is the 7th PID joint and homes with the arm

    def _pre_step(self, t: float) -> None:
        super()._pre_step(t)
        self.jaw._pre_step(t)

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
#: Damped-least-squares steps per tick of the orientation lock, and their damping (rad²).
_LOCK_STEPS = 2
_LOCK_DAMPING = 1e-4
_LOCK_DAMPING_EYE = _LOCK_DAMPING * np.eye(3)


class MTM(Arm):
    """Master tool manipulator of the surgeon console, with its gripper (``mtm.gripper``).

    The gripper is an input: on the real console the operator's fingers set it. Here
    ``mtm.gripper.servo_jp`` stands for the fingers (simulation only); ``gripper.measured_js``
    is what the dVRK publishes.

    ``lock_orientation(R)`` (dvrk.md 2.2, MTM-specific) holds the handle's orientation while the
    arm is in effort mode (``free``, ``body/servo_cf``, ``spatial/servo_cf``): the four wrist
    joints are then position-servoed to an orientation IK solution at every tick and the
    three positioning joints stay in effort mode, so the hand still moves the handle freely.
    In position modes the lock is kept but has no effect, as on the dVRK.
    """

    def __init__(self, name: str, kin: ArmKinematics, sim: Simulation) -> None:
        super().__init__(name, kin, sim)
        assert kin.gripper is not None
        # The fingers are not the arm: they move whatever the arm's state.
        self.gripper = Jaw(self, kin.gripper, "gripper", 4 * np.pi, 8 * np.pi, requires_ready=False)
        self._R_lock: np.ndarray | None = None
        self._wrist_idx = self._idx[MTM_WRIST_JOINTS]
        self._wrist_limits = (
            self.chain.qmin[MTM_WRIST_JOINTS].copy(),
            self.chain.qmax[MTM_WRIST_JOINTS].copy(),
        )

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

    def unlock_orientation(self) -> CommandResult:
        """Let the handle turn freely again in effort mode."""
        self._R_lock = None
        return ACCEPTED

    def orientation_locked(self) -> bool:
        return self._R_lock is not None

    def get_state(self) -> dict:
        """The arm's state (:meth:`Arm.get_state`), the gripper's and the orientation lock."""
        R_lock = None if self._R_lock is None else self._R_lock.copy()
        return {**super().get_state(), "gripper": self.gripper.get_state(), "R_lock": R_lock}

    def set_state(self, state: dict) -> None:
        state = dict(state)
        self.gripper.set_state(state.pop("gripper"))
        R_lock = state.pop("R_lock")
        self._R_lock = None if R_lock is None else R_lock.copy()
        super().set_state(state)

    def _pre_step(self, t: float) -> None:
        super()._pre_step(t)
        self.gripper._pre_step(t)
        servo = self._sim.servo
        if self._R_lock is not None and servo.effort_mode[self._idx[0]]:
            servo.effort_mode[self._wrist_idx] = False
            servo.q_ref[self._wrist_idx] = self._locked_wrist_goal()
            servo.qd_ref[self._wrist_idx] = 0.0

    def _locked_wrist_goal(self) -> np.ndarray:
        """Wrist joints giving the locked orientation with the current arm joints (DLS)."""
        assert self._R_lock is not None
        R_base_goal = self.base_frame()[0][:3, :3].T @ self._R_lock
        q = self._q()
        chain, wrist = self.chain, MTM_WRIST_JOINTS
        for step in range(_LOCK_STEPS):
            # Pose and Jacobian in one kernel pass (the pose is the same bits as FK alone);
            # at the measured joints (the first step) the arm has them already this tick.
            if step == 0:
                T, J_spatial = self._measured_kinematics(jacobian=True)[1:]
            else:
                T, J_spatial = fk.forward_kinematics_and_jacobian(chain, q)
            err = so3.rotation_vector(R_base_goal @ T[:3, :3].T)  # spatial error, base frame
            J = J_spatial[3:, wrist]
            q[wrist] += J.T @ dgesv(J @ J.T + _LOCK_DAMPING_EYE, err)[2]
        lo, hi = self._wrist_limits
        return np.minimum(np.maximum(q[wrist], lo), hi)  # np.clip's arithmetic, less overhead


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
