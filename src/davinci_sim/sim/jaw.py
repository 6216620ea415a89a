"""The 1-DOF jaw of a PSM instrument and the gripper of an MTM (dvrk.md 1.2, 1.5).

The model has two fingers (``<ARM>/jaw_1``, ``<ARM>/jaw_2`` or ``gripper_1/2``); the dVRK
angle is the opening between them, their sum. A command of angle θ servoes each finger to θ/2.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from davinci_sim.kinematics.arms import GripperSpec
from davinci_sim.sim.servo import ServoJoints
from davinci_sim.sim.state import capture, restore
from davinci_sim.sim.trajectory import JointTrajectory, plan_trajectory
from davinci_sim.sim.types import ACCEPTED, CommandResult, JointState
from davinci_sim.sim.validation import ABSURD_FACTOR, as_vector, check_bound, clip_goal

if TYPE_CHECKING:
    from davinci_sim.sim.arm import Arm


def finger_setpoints(angle):
    """Each finger's setpoint (rad) for an opening ``angle`` (rad; or a rate, rad/s): half of
    it (the dVRK angle is the two fingers' sum)."""
    return 0.5 * angle


class Jaw(ServoJoints):
    """``arm.jaw.*`` (PSM) or ``arm.gripper.*`` (MTM)."""

    def __init__(
        self,
        arm: Arm,
        spec: GripperSpec,
        prefix: str,
        v_max: float = np.inf,
        a_max: float = np.inf,
        *,
        requires_ready: bool = True,
    ) -> None:
        self._arm = arm
        self.spec = spec
        servo = arm._sim.servo
        self._bind_servo(servo, [f"{arm.name}/{prefix}_1", f"{arm.name}/{prefix}_2"])
        self._v_max = v_max
        self._a_max = a_max
        self._traj: JointTrajectory | None = None
        self._traj_t0 = 0.0
        # PSM jaw commands need a ready arm (dvrk.md 2.2); MTM fingers need nothing.
        self._requires_ready = requires_ready
        self._command_prefix = spec.name

    @property
    def name(self) -> str:
        return self.spec.name

    def _angle(self) -> float:
        return float(self._arm._sim.data.qpos[self._qposadr].sum())

    def measured_js(self) -> JointState:
        """Opening angle (rad), its rate (rad/s) and the mean finger effort (N·m)."""
        data = self._arm._sim.data
        return JointState(
            (self.spec.name,),
            [self._angle()],
            [float(data.qvel[self._dofadr].sum())],
            [float(data.actuator_force[self._idx].mean())],
            self._arm._now(),
        )

    def setpoint_js(self) -> JointState:
        """The opening setpoint; in effort mode the measured opening (the dVRK PID's)."""
        servo = self._arm._sim.servo
        if servo.effort_mode[self._idx].any():
            return JointState(
                (self.spec.name,),
                [self._angle()],
                [float(self._arm._sim.data.qvel[self._dofadr].sum())],
                [float(servo.tau_ff[self._idx].mean())],
                self._arm._now(),
            )
        return JointState(
            (self.spec.name,),
            [float(servo.q_ref[self._idx].sum())],
            [float(servo.qd_ref[self._idx].sum())],
            [float(servo.tau_ff[self._idx].mean())],
            self._arm._now(),
        )

    def measured_jp(self) -> float:
        return self._angle()

    def _goal(self, command: str, value) -> tuple[float | None, CommandResult]:
        # Joint readiness only: inside the cannula, where Cartesian control is not allowed,
        # the dVRK moves the jaw in joint space (jaw_servo_jp/jaw_move_jp, dvrk.md 2.2).
        why = self._arm._not_ready() if self._requires_ready else ""
        if why:
            return None, self._arm._refuse(f"{self._command_prefix}/{command}", why)
        if isinstance(value, float | int | np.floating | np.integer) and not isinstance(
            value, bool
        ):
            # A plain number (the teleoperation's jaw, the fingers on a gripper, at 1 kHz):
            # checked as a float, without building arrays.
            try:
                v, msg = (value, "") if math.isfinite(value) else (None, f"angle is {value!r}")
            except OverflowError:  # an integer no float holds
                v, msg = None, "angle is too large for a float"
        else:
            v, msg = as_vector(np.atleast_1d(value) if np.ndim(value) == 0 else value, 1, "angle")
        if v is None:
            return None, self._arm._refuse(f"{self._command_prefix}/{command}", msg)
        # Clipped to the jaw's limits as the dVRK's clip_jaw_jp does (dvrk.md 1.2); only a
        # value beyond any joint's reach is refused.
        goal, msg = clip_goal([float(v if np.ndim(v) == 0 else v[0])], self.spec.qmin,
                              self.spec.qmax, (self.spec.name,), "goal")  # fmt: skip
        if goal is None:
            return None, self._arm._refuse(f"{self._command_prefix}/{command}", msg)
        return float(goal[0]), ACCEPTED

    def servo_jp(self, angle) -> CommandResult:
        """Opening angle setpoint (rad) for the next tick."""
        goal, result = self._goal("servo_jp", angle)
        if goal is None:
            return result
        self._traj = None
        self._set(goal, 0.0, effort=None)
        return ACCEPTED

    def _servo_jp_checked(self, angle: float) -> None:
        """:meth:`servo_jp` of an angle known finite and within the jaw's limits, the arm
        ready (the teleoperation's, clamped to the limits, at 1 kHz): not checked again."""
        self._traj = None
        self._set(angle, 0.0, effort=None)

    def move_jp(self, angle) -> CommandResult:
        """Trajectory to the opening angle (rad) within the jaw limits (dvrk.md 1.9)."""
        goal, result = self._goal("move_jp", angle)
        if goal is None:
            return result
        self._start(goal)
        return ACCEPTED

    def servo_jf(self, effort) -> CommandResult:
        """Effort (N·m) on each finger, positive opens; no position control."""
        why = self._arm._not_ready(cartesian=True) if self._requires_ready else ""
        if why:
            return self._arm._refuse(f"{self._command_prefix}/servo_jf", why)
        v, msg = as_vector(np.atleast_1d(effort) if np.ndim(effort) == 0 else effort, 1, "effort")
        if v is None:
            return self._arm._refuse(f"{self._command_prefix}/servo_jf", msg)
        # Clamped to ftmax (dvrk.md 1.2 jaw: 0.16) up to ABSURD_FACTOR x ftmax; refused beyond.
        msg = check_bound(v, ABSURD_FACTOR * self.spec.ftmax, (self.spec.name,), "effort",
                          f"(N·m; {ABSURD_FACTOR:g} x ftmax)")  # fmt: skip
        if msg:
            return self._arm._refuse(f"{self._command_prefix}/servo_jf", msg)
        self._traj = None
        self._set(None, 0.0, effort=float(np.clip(v[0], -self.spec.ftmax, self.spec.ftmax)))
        return ACCEPTED

    # ------------------------------------------------------------ internals
    def _set(self, angle: float | None, rate: float, effort: float | None) -> None:
        servo = self._arm._sim.servo
        if effort is not None:
            servo.effort_mode[self._idx] = True
            servo.tau_ff[self._idx] = effort
            return
        servo.effort_mode[self._idx] = False
        servo.tau_ff[self._idx] = 0.0
        servo.q_ref[self._idx] = finger_setpoints(angle)
        servo.qd_ref[self._idx] = finger_setpoints(rate)

    def _start(self, goal: float) -> None:
        servo = self._arm._sim.servo
        start = float(servo.q_ref[self._idx].sum())
        if servo.effort_mode[self._idx].any():
            start = self._angle()
        self._traj = plan_trajectory([start], [goal], [self._v_max], [self._a_max])
        self._traj_t0 = self._arm._now()
        servo.effort_mode[self._idx] = False
        servo.tau_ff[self._idx] = 0.0

    def _hold(self) -> None:
        self._traj = None
        self._set(self._angle(), 0.0, effort=None)

    def is_busy(self) -> bool:
        return self._traj is not None

    def _pre_step(self, t: float) -> None:
        if self._traj is None:
            return
        q, qd = self._traj.sample(t - self._traj_t0)
        self._set(float(q[0]), float(qd[0]), effort=None)
        if t - self._traj_t0 >= self._traj.duration:
            self._traj = None
            self._arm._publish_state()

    # -------------------------------------------------------------- state
    _STATE = ("_traj", "_traj_t0")

    def get_state(self) -> dict:
        """The trajectory in progress (:mod:`davinci_sim.sim.state`); the fingers' servo
        rows are the simulation's."""
        return capture(self, self._STATE)

    def set_state(self, state: dict) -> None:
        restore(self, state, self._STATE)
