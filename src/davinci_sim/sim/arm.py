"""A simulated dVRK arm with the CRTK API (dvrk.md sections 2.2, 2.4, 3.2).

The arm owns its operating state, its setpoints and its trajectories; the joints move
through real dynamics: setpoints go to the :class:`~davinci_sim.sim.servo.JointServo` and
MuJoCo integrates. Every command is validated first; a refused command leaves the setpoint
unchanged and puts a message on the arm's ``error`` channel.

Frames (dvrk.md 1.1): ``local/measured_cp`` = FK(q) in the chain base (the RCM for PSM/ECM);
``measured_cp`` = base frame · local. The base frame comes from the setup joints (PSM: the
RCM in the ECM tip/camera frame; ECM: in the cart), the console (MTM: in HRSV), or
``set_base_frame``.

Size: over 500 lines because the arm is one class: the CRTK command set (operating state,
joint and Cartesian servo/move, wrenches, kinematics services) reads and changes one
operating state, one setpoint and one trajectory. The formulas the commands use are the
batch-capable laws of :mod:`davinci_sim.sim.arm_laws`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from davinci_sim.geometry.so3 import rotate_pairs
from davinci_sim.kinematics import fk
from davinci_sim.kinematics.arms import ArmKinematics
from davinci_sim.kinematics.ik import inverse_kinematics
from davinci_sim.kinematics.suj import invert_rigid
from davinci_sim.sim import arm_laws as laws
from davinci_sim.sim import operating_state as ops
from davinci_sim.sim.arm_laws import TRACKING_FAULT_TIME, TRACKING_FAULT_TOLERANCE
from davinci_sim.sim.channels import Channels
from davinci_sim.sim.servo import ServoJoints
from davinci_sim.sim.state import capture, restore
from davinci_sim.sim.trajectory import JointTrajectory, plan_trajectory
from davinci_sim.sim.types import (
    ACCEPTED,
    CartesianPose,
    CartesianTwist,
    CommandResult,
    JointState,
    OperatingState,
)
from davinci_sim.sim.validation import (
    ABSURD_FACTOR,
    MAX_JOINT_VALUE,
    as_bool,
    as_number,
    as_transform,
    as_twist,
    as_vector,
    as_wrench,
    check_bound,
    clip_goal,
    short_repr,
)

if TYPE_CHECKING:
    from davinci_sim.sim.simulation import Simulation

__all__ = ["TRACKING_FAULT_TIME", "TRACKING_FAULT_TOLERANCE", "Arm"]
#: Streaming commands (``servo_*``) arrive every tick: after one of them is refused on the
#: error channel for another reason than the two below, further refusals of the same command
#: within this time (s) are counted and reported with the next message instead of flooding
#: the channel (our choice, after the dVRK's throttle of "arm not ready").
STREAMING_REFUSAL_INTERVAL = 1.0
#: Why every command is refused while the arm is not ready starts with this; the dVRK says it
#: at most every 2 s per arm, whatever the command, with the count of refusals since, and
#: starts counting again once a command finds the arm ready (``ArmIsReady``, dvrk.md 2.4).
NOT_READY = "arm not ready"
NOT_READY_INTERVAL = 2.0
#: Why Cartesian commands are refused while the tool or endoscope is inside the cannula
#: contains this; the dVRK says it on the first of a run of such refusals and then once every
#: 1000 (``SetControlSpaceAndMode``, dvrk.md 2.4), the run ending when control is allowed.
IN_CANNULA = "past the cannula"
CANNULA_REFUSAL_PERIOD = 1000


#: servo_jp's velocity feed-forward may be this many times the dVRK's trajectory velocity
#: limit per joint (dvrk.md 1.9) and no more (our bound: a teleoperated tool moves faster
#: than a planned trajectory, but never by orders of magnitude).
FEEDFORWARD_FACTOR = 10.0
#: Smallest trajectory ratio (dvrk.md 1.9 allows ]0, 1]; our bound): 1e-3 already makes a
#: 1 rad move last over half an hour, and a denormal such as 1e-320 overflows the planner.
MIN_TRAJECTORY_RATIO = 1e-3


class Arm(ServoJoints):
    """One arm of the simulation; see the module docstring. Created by the simulation."""

    def __init__(self, name: str, kin: ArmKinematics, sim: Simulation) -> None:
        self.name = name
        self.kin = kin
        self.chain = kin.chain
        self._sim = sim
        servo = sim.servo
        self._bind_servo(servo, [f"{name}/{j}" for j in self.chain.joint_names])
        self.channels = Channels(name)
        self._state = ops.DISABLED
        self._homed = False
        self._paused_from: str | None = None
        self._traj: JointTrajectory | None = None
        self._traj_t0 = 0.0
        self._traj_homing = False
        self._wrench: tuple[str, np.ndarray] | None = None
        self._body_cf_absolute = False
        self._T_user_base: tuple[np.ndarray, str] | None = None
        self._qmin, self._qmax = self.chain.qmin, self.chain.qmax
        self._tol = np.array([TRACKING_FAULT_TOLERANCE[j.joint_type] for j in self.chain.joints])
        self._tracking_adr = self._qposadr.astype(np.int64)  # the kernel's argument types
        self._tracking_idx = self._idx.astype(np.int64)
        self._feedforward_bound = (FEEDFORWARD_FACTOR * kin.v_max).tolist()
        self._tracking_bad_since = math.nan
        """When a joint went out of tracking tolerance, s (nan: none is)."""
        self._trajectory_ratio = 1.0
        self._refusals: dict[str, tuple[float, int]] = {}
        self._kin_cache: list | None = None
        self._inv_base: tuple[np.ndarray, np.ndarray] | None = None
        self._effort_cache: tuple[tuple, np.ndarray] | None = None
        self._base_tick = -1
        self._base: tuple[np.ndarray, str] | None = None
        servo.q_ref[self._idx] = self._q()
        self.local = _LocalView(self)
        self.body = _WrenchView(self, "body")
        self.spatial = _WrenchView(self, "spatial")

    # ------------------------------------------------------------------ helpers
    @property
    def dof(self) -> int:
        return self.chain.dof

    @property
    def tracking_tolerance(self) -> np.ndarray:
        """Per joint, the tracking error that faults the arm after ``TRACKING_FAULT_TIME``."""
        return self._tol.copy()

    def _now(self) -> float:
        return self._sim.time

    def _q(self) -> np.ndarray:
        return self._sim.measured_qpos()[self._qposadr]  # fancy indexing: a new array

    def _measured_kinematics(
        self, jacobian: bool = False
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """``(q, T_base_tip, J_spatial)`` at the measured joints (read-only arrays). Computed
        once per joint configuration: the device, the teleoperation, the wrench and the
        haptic loop all ask for them within one tick. (``jacobian`` is kept for callers
        that document that they need it; both are always computed.)"""
        q = self._q()
        key = q.tobytes()
        c = self._kin_cache
        if c is None or c[0] != key:
            # Both in one pass: whoever asks for the pose this tick asks for the twist too.
            # (q read-only after the call: the kernel's compiled signature is the writable
            # one its warm-up compiled, not a second one compiled inside the loop.)
            T, J = laws.tip_kinematics(self.chain, q)
            c = self._keep_kinematics(q, T, J)
        return c[1], c[2], c[3]

    def _keep_kinematics(self, q: np.ndarray, T_base_tip: np.ndarray, J: np.ndarray) -> list:
        """Hold ``(T_base_tip, J)`` (made read-only, kept) as :meth:`_measured_kinematics`'
        answer at the measured joints ``q``: computed here, or by the same compiled law
        elsewhere (the compiled control period's last tick,
        :mod:`davinci_sim.sim.live_period`)."""
        for a in (q, T_base_tip, J):
            a.setflags(write=False)
        c = self._kin_cache = [q.tobytes(), q, T_base_tip, J]
        return c

    def _qd(self) -> np.ndarray:
        return self._sim.data.qvel[self._dofadr]

    def _effort(self) -> np.ndarray:
        return self._sim.data.actuator_force[self._idx]

    def _q_set(self) -> np.ndarray:
        """The joint position setpoint: the servo's reference, and for joints in effort mode
        the measured position, as the dVRK's PID sets it (dvrk.md 2.2 ``setpoint_js``), so a
        position command after ``free``/``servo_jf``/``servo_cf`` starts where the arm is."""
        servo = self._sim.servo
        q_ref = servo.q_ref[self._idx]  # fancy indexing: a new array
        effort = servo.effort_mode[self._idx]
        return np.where(effort, self._q(), q_ref) if effort.any() else q_ref

    def _refuse(self, command: str, message: str) -> CommandResult:
        """Refuse ``command``, saying why on the error channel, throttled: "arm not ready" and
        "inside the cannula" as the dVRK throttles them, other refusals of a streaming
        command (``servo_*``) once per STREAMING_REFUSAL_INTERVAL."""
        text = f"{command}: {message}"
        now = self._now()
        if message.startswith(NOT_READY):
            last, suppressed = self._refusals.get(NOT_READY, (-np.inf, 0))
            if now - last < NOT_READY_INTERVAL:
                self._refusals[NOT_READY] = (last, suppressed + 1)
                return CommandResult(False, f"{self.name}: {text}")
            if suppressed:
                text += (
                    f" ({suppressed} more refusals because the arm was not ready in the last "
                    f"{now - last:.3g} s)"
                )
            self._refusals[NOT_READY] = (now, 0)
        elif IN_CANNULA in message:
            run = self._refusals.get(IN_CANNULA, (now, 0))[1]
            self._refusals[IN_CANNULA] = (now, run + 1)
            if run % CANNULA_REFUSAL_PERIOD:
                return CommandResult(False, f"{self.name}: {text}")
            if run:
                text += f" ({CANNULA_REFUSAL_PERIOD - 1} more refusals inside the cannula since)"
        elif command.rpartition("/")[2].startswith("servo"):
            last, suppressed = self._refusals.get(command, (-np.inf, 0))
            if now - last < STREAMING_REFUSAL_INTERVAL:
                self._refusals[command] = (last, suppressed + 1)
                return CommandResult(False, f"{self.name}: {text}")
            if suppressed:
                text += f" ({suppressed} more refusals of {command} in the last {now - last:.3g} s)"
            self._refusals[command] = (now, 0)
        self.channels.message("error", text, now)
        return CommandResult(False, f"{self.name}: {text}")

    def _status(self, text: str) -> None:
        self.channels.message("status", text, self._now())

    def _publish_state(self) -> None:
        self.channels.emit("operating_state", self.operating_state())

    def _not_ready(self, cartesian: bool = False) -> str:
        """Why joint (or Cartesian) commands are refused now, or ``""`` (dvrk.md 2.4)."""
        if self._state != ops.ENABLED:
            return f"{NOT_READY}: operating state is {self._state}, needs ENABLED"
        if not self._homed:
            return f"{NOT_READY}: not homed (send state_command 'home' first)"
        if self._traj_homing:
            return f"{NOT_READY}: homing in progress"
        refusals = self._refusals
        if refusals:  # ready: the runs of throttled refusals end
            refusals.pop(NOT_READY, None)
        if cartesian:
            why = self._cartesian_unsafe()
            if not why and refusals:
                refusals.pop(IN_CANNULA, None)
            return why
        return ""

    def _cartesian_unsafe(self) -> str:
        """Arm-specific check before Cartesian control (dvrk.md 2.4); ``""`` if safe."""
        return ""

    # --------------------------------------------------------- operating state
    def operating_state(self) -> OperatingState:
        """``crtk_msgs/OperatingState``: state, is_homed, is_busy (dvrk.md 2.4)."""
        return OperatingState(self._state, self._homed, self.is_busy(), self._now())

    def is_busy(self) -> bool:
        return self._traj is not None

    def is_homed(self) -> bool:
        return self._homed

    def state_command(self, command: str) -> CommandResult:
        """``enable``, ``disable``, ``home``, ``unhome``, ``pause`` or ``resume`` (dvrk.md 2.4)."""
        if not isinstance(command, str):
            return self._refuse("state_command", f"command must be a string, got {command!r}")
        new_state, message = ops.transition(self._state, command)
        if new_state is None:
            self.channels.message("warning", message, self._now())
            return CommandResult(False, f"{self.name}: {message}")
        if command == "enable":
            self._enter(ops.ENABLED, hold=self._state != ops.ENABLED)
        elif command == "disable":
            self._homed = False  # is_homed needs power (dvrk.md 2.4)
            self._enter(ops.DISABLED, hold=True)
        elif command == "home":
            if self._homed and self._state == ops.ENABLED and not self._traj_homing:
                # Already homed and powered: a no-op, as on the dVRK (dvrk.md 2.4, ENABLED:
                # home -> same), so an enable(); home(); move_jp() script run twice does not
                # lose its first move to a second homing.
                self._status("already homed")
                self._publish_state()
            else:
                self._start_homing()
        elif command == "unhome":
            self._homed = False
            self._publish_state()
        elif command == "pause":
            if self._state != ops.PAUSED:
                self._paused_from = self._state
            self._enter(ops.PAUSED, hold=True)
        elif command == "resume":
            self._enter(self._paused_from or ops.ENABLED, hold=False)
        return ACCEPTED

    def _enter(self, state: str, hold: bool) -> None:
        if hold:
            self._hold_here()
        self._state = state
        self._status(f"operating state {state}")
        self._publish_state()

    def _hold_here(self) -> None:
        """Stop any trajectory or effort control and servo the current measured position."""
        self._cancel_trajectory()
        self._wrench = None
        servo = self._sim.servo
        servo.effort_mode[self._idx] = False
        servo.tau_ff[self._idx] = 0.0
        servo.q_ref[self._idx] = self._q()
        servo.qd_ref[self._idx] = 0.0
        self._tracking_bad_since = math.nan

    def _cancel_trajectory(self) -> None:
        was_busy = self._traj is not None
        self._traj = None
        self._traj_homing = False
        if was_busy:
            self._publish_state()

    def _start_homing(self) -> None:
        # Simulated homing goal (dvrk.md 1.7): a trajectory, is_busy while it runs.
        self._homed = False
        self._start_trajectory(self.kin.home, homing=True)
        self._status("homing")

    def _start_trajectory(self, goal: np.ndarray, homing: bool = False) -> None:
        servo = self._sim.servo
        start = self._q_set()  # before leaving effort mode: where the arm is, then
        servo.q_ref[self._idx] = start
        servo.effort_mode[self._idx] = False
        servo.tau_ff[self._idx] = 0.0
        self._wrench = None
        r = self._trajectory_ratio
        self._traj = plan_trajectory(start, goal, self.kin.v_max * r, self.kin.a_max * r)
        self._traj_t0 = self._now()
        self._traj_homing = homing
        self._publish_state()

    # -------------------------------------------------------------- per tick
    def _pre_step(self, t: float) -> None:
        """Update servo references for the coming physics step (called by the simulation)."""
        servo = self._sim.servo
        if self._traj is not None:
            q, qd = self._traj.sample(t - self._traj_t0)
            servo.q_ref[self._idx] = q
            servo.qd_ref[self._idx] = qd
            if t - self._traj_t0 >= self._traj.duration:
                homing = self._traj_homing
                self._traj = None
                self._traj_homing = False
                if homing:
                    self._homed = True
                    self._status("homed")
                self._publish_state()
        if self._wrench is not None:
            servo.tau_ff[self._idx] = self._wrench_to_effort(*self._wrench)
        # (The tracking watch runs after every arm's setpoints: sim/tracking_watch.py.)

    def _pre_step_idle(self) -> bool:
        """Whether :meth:`_pre_step` has nothing to do now (no trajectory, no wrench): ticks
        may then run without calling it (:mod:`davinci_sim.sim.live_period`)."""
        return self._traj is None and self._wrench is None

    def _tracking_fault(self, i: int) -> None:
        """The tracking watch found joint ``i`` out of tolerance for too long: FAULT."""
        err = abs(float(self._q()[i]) - float(self._sim.servo.q_ref[self._idx[i]]))
        self._fault(
            f"tracking error on joint {self.chain.joint_names[i]!r}: {err:.4g} exceeds "
            f"{self._tol[i]:.4g}"
        )

    def _fault(self, reason: str) -> None:
        """Go to FAULT holding where the joints are, saying ``reason`` on ``error``."""
        self.channels.message("error", f"{reason}; arm in FAULT", self._now())
        self._hold_here()
        self._state = ops.FAULT
        self._publish_state()

    # ------------------------------------------------------------ joint space
    def measured_js(self) -> JointState:
        """Joint positions, velocities and efforts (``sensor_msgs/JointState``)."""
        return JointState(
            self.chain.joint_names, self._q(), self._qd(), self._effort(), self._now()
        )

    def setpoint_js(self) -> JointState:
        """The servo's setpoint; in effort mode the measured position and velocity (the
        dVRK's PID setpoint there, dvrk.md 2.2) and the commanded efforts."""
        servo = self._sim.servo
        qd_ref = servo.qd_ref[self._idx]
        effort = servo.effort_mode[self._idx]
        if effort.any():
            qd_ref = np.where(effort, self._qd(), qd_ref)
        return JointState(
            self.chain.joint_names,
            self._q_set(),
            qd_ref,
            servo.tau_ff[self._idx],
            self._now(),
        )

    def measured_jp(self) -> np.ndarray:
        return self._q()

    def setpoint_jp(self) -> np.ndarray:
        return self._q_set()

    def _joint_goal(self, command: str, value, relative: bool) -> tuple[np.ndarray | None, str]:
        why = self._not_ready()
        if why:
            return None, why
        v, msg = as_vector(value, self.dof, "position" if not relative else "increment")
        if v is None:
            return None, msg
        goal = self._q_set() + v if relative else v
        # Clipped to the joint limits, not refused: the dVRK clips every joint goal of a
        # homed arm (clip_jp, dvrk.md 1.2-1.5 limits), so an arm resting a hair past a limit
        # still takes goals made from its setpoint.
        return clip_goal(goal, self._qmin, self._qmax, self.chain.joint_names, "goal")

    def servo_jp(self, position, velocity=None) -> CommandResult:
        """Joint position setpoint for the next tick (optional velocity feed-forward)."""
        goal, msg = self._joint_goal("servo_jp", position, relative=False)
        if goal is None:
            return self._refuse("servo_jp", msg)
        qd = np.zeros(self.dof)
        if velocity is not None and len(np.atleast_1d(velocity)) > 0:
            qd, msg = as_vector(velocity, self.dof, "velocity")
            if qd is None:
                return self._refuse("servo_jp", msg)
            # A feed-forward far beyond anything the arm can do would swing it into a
            # tracking fault, or (1e300) make the physics diverge: bounded per joint at
            # FEEDFORWARD_FACTOR times the dVRK's trajectory velocity limit (dvrk.md 1.9).
            msg = self._feedforward_over(qd, "velocity")
            if msg:
                return self._refuse("servo_jp", msg)
        self._servo_position(goal, qd)
        return ACCEPTED

    def _feedforward_over(self, qd: np.ndarray, what: str) -> str:
        """Message if a joint velocity feed-forward is over FEEDFORWARD_FACTOR x the dVRK's
        trajectory limit of its joint (dvrk.md 1.9), else ``""``."""
        return check_bound(qd, self._feedforward_bound, self.chain.joint_names,
                           what, f"(rad/s or m/s; {FEEDFORWARD_FACTOR:g} x the dVRK trajectory "
                           "limit)")  # fmt: skip

    def servo_jr(self, increment) -> CommandResult:
        """Add ``increment`` to the current joint setpoint."""
        goal, msg = self._joint_goal("servo_jr", increment, relative=True)
        if goal is None:
            return self._refuse("servo_jr", msg)
        self._servo_position(goal, np.zeros(self.dof))
        return ACCEPTED

    def _servo_position(self, goal: np.ndarray, qd: np.ndarray) -> None:
        self._cancel_trajectory()
        self._wrench = None
        servo = self._sim.servo
        servo.effort_mode[self._idx] = False
        servo.tau_ff[self._idx] = 0.0
        servo.q_ref[self._idx] = goal
        servo.qd_ref[self._idx] = qd

    def servo_jf(self, effort) -> CommandResult:
        """Joint efforts (N·m, N) on top of gravity compensation; no position control."""
        why = self._not_ready()
        if why:
            return self._refuse("servo_jf", why)
        e, msg = as_vector(effort, self.dof, "effort")
        if e is None:
            return self._refuse("servo_jf", msg)
        # Up to ABSURD_FACTOR x a joint's ftmax: clamped to ftmax as the dVRK's controller
        # does (dvrk.md 1.1); beyond: an error, refused.
        msg = check_bound(e, ABSURD_FACTOR * self.chain.ftmax, self.chain.joint_names,
                          "effort", f"(N·m or N; {ABSURD_FACTOR:g} x ftmax)")  # fmt: skip
        if msg:
            return self._refuse("servo_jf", msg)
        self._set_effort(np.clip(e, -self.chain.ftmax, self.chain.ftmax))
        return ACCEPTED

    def _set_effort(self, effort: np.ndarray) -> None:
        self._cancel_trajectory()
        self._wrench = None
        servo = self._sim.servo
        servo.effort_mode[self._idx] = True
        servo.tau_ff[self._idx] = effort
        servo.qd_ref[self._idx] = 0.0

    def move_jp(self, goal) -> CommandResult:
        """Trajectory to ``goal`` within the dVRK limits (dvrk.md 1.9); ``is_busy`` meanwhile."""
        q, msg = self._joint_goal("move_jp", goal, relative=False)
        if q is None:
            return self._refuse("move_jp", msg)
        self._start_trajectory(q)
        return ACCEPTED

    def move_jr(self, increment) -> CommandResult:
        """Trajectory to the current setpoint + ``increment``."""
        q, msg = self._joint_goal("move_jr", increment, relative=True)
        if q is None:
            return self._refuse("move_jr", msg)
        self._start_trajectory(q)
        return ACCEPTED

    def hold(self) -> CommandResult:
        """Stop moving and keep the current position."""
        if self._state != ops.ENABLED:
            return self._refuse("hold", f"{NOT_READY}: operating state is {self._state}")
        self._hold_here()
        return ACCEPTED

    def free(self) -> CommandResult:
        """Zero effort plus gravity compensation: the arm can be moved by hand."""
        if self._state != ops.ENABLED:
            return self._refuse("free", f"{NOT_READY}: operating state is {self._state}")
        self._set_effort(np.zeros(self.dof))
        return ACCEPTED

    def use_gravity_compensation(self, enabled: bool) -> CommandResult:
        on, msg = as_bool(enabled, "enabled")
        if on is None:
            return self._refuse("use_gravity_compensation", msg)
        self._sim.servo.gravity_compensation[self._idx] = on
        return ACCEPTED

    def trajectory_j_set_ratio(self, ratio: float) -> CommandResult:
        """Scale the ``move_*`` velocity and acceleration limits, ratio in ]0, 1] (dvrk.md 1.9)."""
        r, msg = as_number(ratio, "ratio")  # not a bool, not a 400-digit integer
        if r is None:
            return self._refuse("trajectory_j/set_ratio", msg)
        if not (MIN_TRAJECTORY_RATIO <= r <= 1.0):
            return self._refuse(
                "trajectory_j/set_ratio",
                f"ratio must be in [{MIN_TRAJECTORY_RATIO:g}, 1], got {r:.4g}",
            )
        self._trajectory_ratio = r
        return ACCEPTED

    def trajectory_j_ratio(self) -> float:
        return self._trajectory_ratio

    # -------------------------------------------------------------- Cartesian
    def base_frame(self) -> tuple[np.ndarray, str]:
        """``(T_reference_base, reference frame name)`` used for ``measured_cp``."""
        if self._T_user_base is not None:
            return self._T_user_base
        tick = self._sim.tick_count
        if self._base_tick != tick:  # asked many times per tick: once to the simulation
            self._base = self._sim.default_base_frame(self.name)
            self._base_tick = tick
        return self._base

    def _T_base_reference(self) -> np.ndarray:
        """Inverse of the base frame, recomputed only when the base frame changes."""
        T_ref_base = self.base_frame()[0]
        cached = self._inv_base
        if cached is None or cached[0] is not T_ref_base:
            # (the compiled control period's arithmetic: sim/live_kernel.py, the same bits)
            inverse = np.empty((4, 4))
            invert_rigid(np.ascontiguousarray(T_ref_base, dtype=float), inverse)
            cached = self._inv_base = (T_ref_base, inverse)
        return cached[1]

    def set_base_frame(self, T_reference_base, reference_frame: str = "") -> CommandResult:
        """Runtime base frame, as the dVRK ``set_base_frame`` (dvrk.md 1.1)."""
        T, msg = as_transform(T_reference_base, "base frame")
        if T is None:
            return self._refuse("set_base_frame", msg)
        if not isinstance(reference_frame, str) or len(reference_frame) > 256:
            return self._refuse(
                "set_base_frame",
                f"reference_frame must be a name (a string of up to 256 characters), got "
                f"{short_repr(reference_frame)}",
            )
        self._T_user_base = (T, reference_frame or f"{self.name}_reference")
        return ACCEPTED

    def _pose(self, q: np.ndarray, moving: str, local: bool) -> CartesianPose:
        T_base_tip = laws.tip_pose(self.chain, q)
        if local:
            return CartesianPose(T_base_tip, f"{self.name}_base", moving, self._now())
        T_ref_base, ref = self.base_frame()
        T = laws.pose_in_reference(T_ref_base, T_base_tip)
        return CartesianPose(T, ref, moving, self._now())

    def measured_cp(self) -> CartesianPose:
        """Tool tip in the base frame's reference (PSM: camera, ECM: cart, MTM: HRSV)."""
        _, T_base_tip, _ = self._measured_kinematics()
        T_ref_base, ref = self.base_frame()
        T = laws.pose_in_reference(T_ref_base, T_base_tip)
        return CartesianPose(T, ref, self.name, self._now())

    def setpoint_cp(self) -> CartesianPose:
        return self._pose(self._q_set(), f"{self.name}_setpoint", local=False)

    def _measured_T(self) -> np.ndarray:
        """``measured_cp().T`` without building the message: a new read-only 4x4 (m), the
        same bits (for the simulator's own per-tick readers: devices, haptics, tasks)."""
        _, T_base_tip, _ = self._measured_kinematics()
        T = laws.pose_in_reference(self.base_frame()[0], T_base_tip)
        T.setflags(write=False)
        return T

    def _measured_twist(self) -> np.ndarray:
        """``measured_cv().twist`` without building the message: a new read-only (6,)
        (m/s, rad/s), the same bits."""
        J = self._measured_kinematics(jacobian=True)[2]
        twist = laws.twist_in_reference(self.base_frame()[0][:3, :3], J, self._qd())
        twist.setflags(write=False)
        return twist

    def measured_cv(self) -> CartesianTwist:
        """Tip twist (linear m/s, angular rad/s) in the base frame's orientation (dvrk.md 2.2)."""
        J = self._measured_kinematics(jacobian=True)[2]
        T_ref_base, ref = self.base_frame()
        twist = laws.twist_in_reference(T_ref_base[:3, :3], J, self._qd())
        return CartesianTwist(twist, ref, self.name, self._now())

    def _cartesian_goal(self, command: str, T_goal, seed: np.ndarray, checked: bool = False):
        why = self._not_ready(cartesian=True)
        if why:
            return None, why
        T, msg = (T_goal, "") if checked else as_transform(T_goal, "goal")
        if T is None:
            return None, msg
        T_base_goal = self._T_base_reference() @ T  # IK works in the chain base (dvrk.md 1.8)
        result = inverse_kinematics(self.kin, T_base_goal, seed)
        if not (result.success or result.reached):  # reached: only past a joint limit
            return None, f"inverse kinematics failed: {result.message}"
        # The dVRK clips the IK solution to the joint limits too (clip_jp after IK).
        return clip_goal(result.q, self._qmin, self._qmax, self.chain.joint_names, "IK")

    def servo_cp(self, T_goal, twist=None) -> CommandResult:
        """Cartesian setpoint in the base frame's reference; IK seeded with measured joints."""
        return self._servo_cp(T_goal, twist, checked=False)

    def _servo_cp_checked(self, T_goal: np.ndarray, twist=None) -> CommandResult:
        """:meth:`servo_cp` of a goal known to be a proper 4x4 transform within reach (the
        teleoperation's, composed of measured poses and rotations at 1 kHz): the goal is not
        checked again; everything else is as :meth:`servo_cp` (readiness, IK, limits, the
        twist and its feed-forward bound)."""
        return self._servo_cp(T_goal, twist, checked=True)

    def _servo_cp(self, T_goal, twist, checked: bool) -> CommandResult:
        q_now = self._q()
        q, msg = self._cartesian_goal("servo_cp", T_goal, q_now, checked)
        if q is None:
            return self._refuse("servo_cp", msg)
        if self.kin.arm_type == "PSM" and laws.other_branch(q, q_now):
            turn = np.degrees(np.abs(q[3:6] - q_now[3:6]).max())
            return self._refuse("servo_cp", "the goal is past the wrist's reach on its "
                                f"branch (its IK turns a wrist joint {turn:.0f}°): the tool "
                                "is held")  # fmt: skip
        qd = np.zeros(self.dof)
        if twist is not None:
            tw, msg = as_twist(twist, "twist")
            if tw is None:
                return self._refuse("servo_cp", msg)
            local = rotate_pairs(self.base_frame()[0][:3, :3].T, tw)
            # The Jacobian at the measured joints (cached this tick), as a servo loop does.
            qd = laws.joint_velocity(self._measured_kinematics(jacobian=True)[2], local)
            # Near a singularity a modest twist needs huge joint rates: the same bound as
            # servo_jp's velocity (FEEDFORWARD_FACTOR x the dVRK trajectory limit).
            msg = self._feedforward_over(qd, "twist as joint velocity")
            if msg:
                return self._refuse("servo_cp", msg)
        self._servo_position(q, qd)
        return ACCEPTED

    def move_cp(self, T_goal) -> CommandResult:
        """IK once, then a joint trajectory (not a straight line, as the dVRK; dvrk.md 1.9)."""
        q, msg = self._cartesian_goal("move_cp", T_goal, self._q_set())
        if q is None:
            return self._refuse("move_cp", msg)
        self._start_trajectory(q)
        return ACCEPTED

    def forward_kinematics(self, jp) -> tuple[CartesianPose | None, CommandResult]:
        """Pose of the frame after ``len(jp)`` joints, with the base frame (dvrk.md 2.2)."""
        q = _joint_query(jp, self.dof)
        if q is None:
            return None, self._refuse(
                "forward_kinematics",
                f"needs 1..{self.dof} finite joint values within ±{MAX_JOINT_VALUE:g}, "
                f"got {short_repr(jp)}",
            )
        chain = self.chain.truncated(q.shape[0], with_tool=True)
        T_ref_base, ref = self.base_frame()
        T = T_ref_base @ fk.forward_kinematics(chain, q)
        return CartesianPose(T, ref, self.name, self._now()), ACCEPTED

    def inverse_kinematics(self, jp, T_goal) -> tuple[np.ndarray | None, CommandResult]:
        """Joints reaching ``T_goal`` (base frame's reference) seeded with ``jp``."""
        seed, msg = as_vector(jp, self.dof, "reference joints")
        if seed is not None:
            msg = check_bound(seed, MAX_JOINT_VALUE, self.chain.joint_names,
                              "reference joints", "(rad or m)")  # fmt: skip
            seed = None if msg else seed
        T, msg2 = as_transform(T_goal, "goal")
        if seed is None or T is None:
            return None, self._refuse("inverse_kinematics", msg or msg2)
        result = inverse_kinematics(self.kin, np.linalg.inv(self.base_frame()[0]) @ T, seed)
        if not result.success:
            return None, self._refuse("inverse_kinematics", result.message)
        return result.q, ACCEPTED

    # -------------------------------------------------------------- wrenches
    def _wrench_to_effort(self, kind: str, w: np.ndarray) -> np.ndarray:
        if not w.any():  # zero (no NaN): Jᵀ·0 is +0.0 at any joints, as the law computes it
            return np.zeros(self.dof)
        # Cached: servo_cf and the next _pre_step ask for the same joints and wrench.
        q, T_base_tip, Js = self._measured_kinematics(jacobian=True)
        # The same cached q and base-frame objects mean the same joints and frame.
        key = (q, self.base_frame()[0], kind, w.tobytes(), self._body_cf_absolute)
        cached = self._effort_cache
        if (
            cached is not None
            and cached[0][0] is key[0]
            and cached[0][1] is key[1]
            and cached[0][2:] == key[2:]
        ):
            return cached[1].copy()
        tau = self._compute_effort(kind, w, T_base_tip, Js)
        self._effort_cache = (key, tau)
        return tau.copy()

    def _compute_effort(self, kind: str, w: np.ndarray, T_base_tip, Js) -> np.ndarray:
        if kind == "body" and not self._body_cf_absolute:
            R_base_tip = T_base_tip[:3, :3]
        else:  # expressed in the reference (base-frame) orientation
            R_base_tip = self.base_frame()[0][:3, :3].T
        return laws.wrench_effort(Js, R_base_tip, w, self.chain.ftmax)

    def _servo_cf(self, kind: str, wrench, checked: bool = False) -> CommandResult:
        """``servo_cf`` of ``kind`` (body or spatial); ``checked``: ``wrench`` is already a
        checked (6,) float array within the bounds (the haptic loop's clamped sum: validated
        once, at the edge it came in by)."""
        why = self._not_ready()
        if why:
            return self._refuse(f"{kind}/servo_cf", why)
        w, msg = (wrench, "") if checked else as_wrench(wrench, "wrench")
        if w is None:
            return self._refuse(f"{kind}/servo_cf", msg)
        if self._wrench is None or self._wrench[0] != kind:  # entering this wrench mode
            self._set_effort(np.zeros(self.dof))
        self._wrench = (kind, w)
        self._sim.servo.tau_ff[self._idx] = self._wrench_to_effort(kind, w)
        return ACCEPTED

    def _hold_wrench_effort(
        self, kind: str, w: np.ndarray, tau: np.ndarray, q: np.ndarray, T_ref_base: np.ndarray
    ) -> None:
        """What ``_servo_cf(kind, w, checked=True)`` leaves, for an arm ready and in ``kind``
        wrench mode already, with ``tau`` its efforts computed by the caller (the compiled
        haptic render, ``devices/device_row.py``) at the joints ``q`` and base frame
        ``T_ref_base`` (the objects ``_measured_kinematics`` and ``base_frame`` return now,
        so that the next pre-step's ``_wrench_to_effort`` finds them cached)."""
        self._wrench = (kind, w)
        self._effort_cache = ((q, T_ref_base, kind, w.tobytes(), self._body_cf_absolute), tau)
        self._sim.servo.tau_ff[self._idx] = tau

    def _measured_cf(self, kind: str) -> np.ndarray:
        """Wrench at the tip estimated from joint efforts minus gravity compensation."""
        _, T_base_tip, Js = self._measured_kinematics(jacobian=True)
        tau = self._effort() - self._sim.data.qfrc_bias[self._dofadr]
        w = np.linalg.lstsq(Js.T, tau, rcond=None)[0]
        if kind == "body" and not self._body_cf_absolute:
            R = T_base_tip[:3, :3].T
        else:
            R = self.base_frame()[0][:3, :3]
        return np.concatenate([R @ w[:3], R @ w[3:]])

    def wrench_setpoint(self) -> tuple[str, np.ndarray] | None:
        """The wrench ``body/servo_cf`` or ``spatial/servo_cf`` applies now: ``(kind, wrench)``,
        or None when the arm is in another mode."""
        if self._wrench is None:
            return None
        return self._wrench[0], self._wrench[1].copy()

    def body_set_cf_orientation_absolute(self, absolute: bool) -> CommandResult:
        """Express ``body`` wrenches in the base frame's orientation instead of the tip's."""
        on, msg = as_bool(absolute, "absolute")
        if on is None:
            return self._refuse("body/set_cf_orientation_absolute", msg)
        self._body_cf_absolute = on
        return ACCEPTED

    # -------------------------------------------------------------- state
    #: What :meth:`get_state` saves: operating state, homing, the trajectory in progress,
    #: the wrench mode, a base frame set at run time, the tracking-fault watch, the
    #: trajectory ratio and the refusal throttle. The servo rows are the simulation's.
    _STATE = (
        "_state",
        "_homed",
        "_paused_from",
        "_traj",
        "_traj_t0",
        "_traj_homing",
        "_wrench",
        "_body_cf_absolute",
        "_T_user_base",
        "_tracking_bad_since",
        "_trajectory_ratio",
        "_refusals",
    )

    def get_state(self) -> dict:
        """The arm's own state (:mod:`davinci_sim.sim.state`), deep-copied."""
        return capture(self, self._STATE)

    def set_state(self, state: dict) -> None:
        """Put back a :meth:`get_state`; the arm's caches of poses and efforts are dropped
        (they are recomputed from the restored joints and frames)."""
        restore(self, state, self._STATE)
        self._kin_cache = self._inv_base = self._effort_cache = self._base = None
        self._base_tick = -1

    def user_base_frame(self) -> tuple[np.ndarray, str] | None:
        """The base frame set at run time (:meth:`set_base_frame`): ``(T_reference_base,
        reference frame)``, or None while the arm uses the system's default."""
        return self._T_user_base


def _joint_query(jp, dof: int) -> np.ndarray | None:
    """``jp`` as 1..``dof`` finite joint values within ±MAX_JOINT_VALUE, or None."""
    try:
        q = np.asarray(jp, dtype=float) if np.ndim(jp) == 1 else None
    except (TypeError, ValueError):
        return None
    if q is None or not (1 <= q.shape[0] <= dof) or not (np.abs(q) <= MAX_JOINT_VALUE).all():
        return None
    return q


class _LocalView:
    """``arm.local.*``: the same quantities without the base frame (dvrk.md 2.2)."""

    def __init__(self, arm: Arm) -> None:
        self._arm = arm

    def measured_cp(self) -> CartesianPose:
        arm = self._arm
        T = arm._measured_kinematics()[1].copy()
        return CartesianPose(T, f"{arm.name}_base", arm.name, arm._now())

    def setpoint_cp(self) -> CartesianPose:
        return self._arm._pose(self._arm._q_set(), f"{self._arm.name}_setpoint", local=True)

    def measured_cv(self) -> CartesianTwist:
        """Twist in the tip (body) frame."""
        arm = self._arm
        _, T, J = arm._measured_kinematics(jacobian=True)
        R = T[:3, :3].T
        v = np.concatenate([R @ J[:3], R @ J[3:]]) @ arm._qd()
        return CartesianTwist(v, arm.name, arm.name, arm._now())

    def forward_kinematics(self, jp) -> tuple[CartesianPose | None, CommandResult]:
        arm = self._arm
        q = _joint_query(jp, arm.dof)
        if q is None:
            return None, arm._refuse(
                "local/forward_kinematics",
                f"needs 1..{arm.dof} finite joint values within ±{MAX_JOINT_VALUE:g}, "
                f"got {short_repr(jp)}",
            )
        T = fk.forward_kinematics(arm.chain.truncated(q.shape[0], with_tool=True), q)
        return CartesianPose(T, f"{arm.name}_base", arm.name, arm._now()), ACCEPTED


class _WrenchView:
    """``arm.body.*`` and ``arm.spatial.*``: Cartesian wrench commands, readings, Jacobians."""

    def __init__(self, arm: Arm, kind: str) -> None:
        self._arm = arm
        self._kind = kind

    def servo_cf(self, wrench) -> CommandResult:
        """Force (N) then torque (N·m) at the tip; body: tip frame, spatial: base orientation."""
        return self._arm._servo_cf(self._kind, wrench)

    def measured_cf(self) -> np.ndarray:
        return self._arm._measured_cf(self._kind)

    def jacobian(self) -> np.ndarray:
        _, T, J = self._arm._measured_kinematics(jacobian=True)
        if self._kind == "body":
            R = T[:3, :3].T
            return np.vstack([R @ J[:3], R @ J[3:]])
        R = self._arm.base_frame()[0][:3, :3]
        return np.vstack([R @ J[:3], R @ J[3:]])
