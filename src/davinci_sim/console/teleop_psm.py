"""PSM teleoperation with the dVRK's semantics (dvrk.md 4.2), e.g. ``MTMR_PSM1``.

State machine: DISABLED → SETTING_ARMS_STATE → ALIGNING_MTM → ENABLED (one transition per
tick at most):

* SETTING_ARMS_STATE: enable and home the PSM and the MTM device if needed; wait until both
  are ready (60 s, then an error and DISABLED).
* ALIGNING_MTM: move the MTM to the PSM's orientation (``align_MTM``), watch for operator
  activity (gripper/roll motion over the thresholds), and start following once the
  orientation error is within 5°, the operator is active, the MTM is not moving and the
  desired state is ENABLED. A warning every 2 s says what is missing.
* ENABLED: the initial poses and the alignment offset are stored; the MTM is put in effort
  mode (gravity compensation, zero wrench, orientation locked only if rotation is locked) and
  the PSM follows (:mod:`~davinci_sim.console.teleop_math`) with velocity feed-forward, the
  jaw follows the gripper within the jaw rate.

Clutch: the PSM holds, the MTM orientation locks, and on release the teleoperation goes
through SETTING_ARMS_STATE and ALIGNING_MTM again, re-anchoring the initial poses: no jump.
If the PSM or the MTM leaves ENABLED/homed, the teleoperation goes DISABLED with an error; if
a networked MTM device goes stale (30 ms watchdog, dvrk.md 1.7), following stops with an
error and the teleoperation waits in SETTING_ARMS_STATE for fresh input, then re-aligns.

Size: over 500 lines because the state machine above is one class whose states share the
anchors, the alignment and the clutch handling; its laws (following, jaw) are the
batch-capable functions of :mod:`~davinci_sim.console.teleop_math`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from davinci_sim.console import teleop_math as tm
from davinci_sim.console.teleop_base import TeleopBase
from davinci_sim.console.teleop_config import TeleopPSMConfig
from davinci_sim.devices.device import MasterDevice
from davinci_sim.geometry import so3
from davinci_sim.kinematics import jit
from davinci_sim.sim.arms import PSM
from davinci_sim.sim.channels import Channels
from davinci_sim.sim.state import capture, restore
from davinci_sim.sim.types import ACCEPTED, CommandResult
from davinci_sim.sim.validation import short_repr

_ROW = None  # the following tick's compiled rows (console/teleop_row.py), when numba compiles
if jit.ENABLED:
    from davinci_sim.console import teleop_row as _row_module

    if jit.warmed_up(_row_module._warm_up, "the teleoperation's compiled tick: Python runs"):
        _ROW = _row_module

if TYPE_CHECKING:
    from davinci_sim.sim.simulation import Simulation

DISABLED = "DISABLED"
SETTING_ARMS_STATE = "SETTING_ARMS_STATE"
ALIGNING_MTM = "ALIGNING_MTM"
ENABLED = "ENABLED"
STATES = (DISABLED, SETTING_ARMS_STATE, ALIGNING_MTM, ENABLED)
#: dvrk.md 4.2: ``state_command`` strings (the docs write ``align_mtm``, the code
#: ``align_MTM``: both are accepted).
COMMANDS = {"enable": ENABLED, "disable": DISABLED, "align_MTM": ALIGNING_MTM}
COMMANDS["align_mtm"] = ALIGNING_MTM


@dataclass(frozen=True, eq=False)
class TeleopPSMState:
    """What a PSM teleoperation publishes (dvrk.md 4.3, ``/<MTM>_<PSM>/…``)."""

    name: str
    mtm: str
    psm: str
    current_state: str
    desired_state: str
    following: bool
    scale: float
    rotation_locked: bool
    translation_locked: bool
    align_mtm: bool
    alignment_offset: np.ndarray
    """``R_mtmᵀ·R_psm`` stored when following started (3x3)."""
    selected: bool
    clutched: bool
    T_hrsv_mtm: np.ndarray | None
    """The MTM pose the teleoperation last read (HRSV), None before any input."""


@dataclass(frozen=True, eq=False)
class FollowingAnchors:
    """What following started from (dvrk.md 4.2), for code that continues the following law
    elsewhere (the study's batch engine)."""

    T_camera_psm0: np.ndarray
    """PSM pose when following (re)started, camera frame."""
    T_hrsv_mtm0: np.ndarray
    """MTM pose then, HRSV."""
    R_offset: np.ndarray
    """``R_mtmᵀ·R_psm`` alignment offset."""
    scale: float
    translation_locked: bool
    rotation_locked: bool
    jaw_scale: float
    jaw_offset: float
    """``jaw = jaw_scale·gripper + jaw_offset``."""
    jaw_ghost: float
    """The gripper value the jaw follows now (moves towards the gripper at ``jaw_rate``)."""
    jaw_sent: float
    """The jaw angle last sent (nan: none yet)."""
    jaw_catching_up: bool = False
    """True while the jaw catches up with the gripper after a clutch (at
    ``config.jaw_rate_after_clutch``, until within ``JAW_CATCH_UP_TOLERANCE``)."""


class TeleopPSM(TeleopBase):
    """The teleoperation of ``psm`` by the master ``device``; see the module docstring.

    Args:
        sim: the simulation.
        device: the MTM device.
        mtm: the MTM's name, for the teleoperation's name ``<mtm>_<psm>``.
        psm: the PSM's name.
        config: settings (dvrk.md 4.1).
    """

    def __init__(
        self,
        sim: Simulation,
        device: MasterDevice,
        *,
        mtm: str,
        psm: str,
        config: TeleopPSMConfig | None = None,
    ) -> None:
        arm = sim.arms.get(psm)
        if not isinstance(arm, PSM):
            psms = [n for n, a in sim.arms.items() if isinstance(a, PSM)]
            raise KeyError(f"no PSM {psm!r} in this simulation; PSMs: {psms}")
        self.sim = sim
        self.device = device
        self.psm = arm
        self.mtm_name = mtm
        self.psm_name = psm
        self.name = f"{mtm}_{psm}"
        self.config = config or TeleopPSMConfig()
        self.channels = Channels(self.name)
        self._dt = sim.dt
        # settings that commands change (dvrk.md 4.3)
        self._scale = self.config.scale
        self._rotation_locked = self.config.rotation_locked
        self._translation_locked = self.config.translation_locked
        self._align = self.config.align_mtm and device.can_align
        self._haptic = self.config.mtm_is_haptic and device.is_haptic
        self._ignore_jaw = self.config.ignore_jaw
        # state machine
        self._current = DISABLED
        self._desired = DISABLED
        self._entered_at = 0.0
        self._following = False
        self._clutched = False
        self.selected = False
        # ALIGNING_MTM
        self._align_goal: np.ndarray | None = None
        self._next_warning = 0.0
        self._gripper_range = [math.inf, -math.inf]
        self._roll_range = [math.inf, -math.inf]
        self._operator_active = False
        self._operator_was_active = False
        # ENABLED
        self._T_camera_psm0 = np.eye(4)
        self._T_hrsv_mtm0 = np.eye(4)
        self._R_offset = np.eye(3)
        self._jaw_s, self._jaw_o = 1.0, 0.0
        self._ghost = 0.0
        self._jaw_catching_up = False
        self._jaw_sent = math.nan
        # the compiled following tick's arguments (:meth:`_follow_compiled`), reused
        self._row_flags = np.zeros(5)
        self._row_jaw = np.zeros(12)
        if self.config.align_mtm and not device.can_align:
            self.channels.message(
                "status",
                f"{device.name} ({device.kind}) cannot be moved: align_MTM off, the alignment "
                "offset absorbs the orientation difference",
                sim.time,
            )

    # ------------------------------------------------------------ dVRK API (dvrk.md 4.3)
    def state_command(self, command: str) -> CommandResult:
        """``enable``, ``disable`` or ``align_MTM`` (sets the desired state)."""
        desired = COMMANDS.get(command) if isinstance(command, str) else None
        if desired is None:
            return self._refuse(
                "state_command",
                f"unknown command {command!r}; valid: enable, disable, align_MTM",
            )
        self._set_desired(desired)
        return ACCEPTED

    def set_scale(self, scale: float) -> CommandResult:
        """Translation scale in ]0, 1] (dvrk.md 4.1); re-anchors without a jump."""
        s = tm.as_scale(scale)
        if not (0.0 < s <= 1.0):
            return self._refuse("set_scale", f"scale must be in ]0, 1], got {short_repr(scale)}")
        self._scale = s
        self.channels.emit("scale", s)
        self._reanchor()
        return ACCEPTED

    def lock_translation(self, lock: bool) -> CommandResult:
        """Hold the PSM position (re-anchors without a jump)."""
        if not isinstance(lock, bool | np.bool_):
            return self._refuse("lock_translation", f"needs a bool, got {lock!r}")
        self._translation_locked = bool(lock)
        self.channels.emit("translation_locked", self._translation_locked)
        self._reanchor()
        return ACCEPTED

    def lock_rotation(self, lock: bool) -> CommandResult:
        """Hold the PSM orientation; unlocking re-aligns (dvrk.md 4.2)."""
        if not isinstance(lock, bool | np.bool_):
            return self._refuse("lock_rotation", f"needs a bool, got {lock!r}")
        self._rotation_locked = bool(lock)
        self.channels.emit("rotation_locked", self._rotation_locked)
        if self._rotation_locked:
            self._reanchor()
            if self._current == ENABLED and self._haptic:
                self.device.lock_orientation(self._mtm_T()[:3, :3])
        else:
            self._restart_if_enabled()
        return ACCEPTED

    def set_align_mtm(self, align: bool) -> CommandResult:
        """Require the MTM orientation to match the PSM's (re-aligns, dvrk.md 4.2)."""
        if not isinstance(align, bool | np.bool_):
            return self._refuse("set_align_MTM", f"needs a bool, got {align!r}")
        if align and not self.device.can_align:
            return self._refuse(
                "set_align_MTM", f"{self.device.name} ({self.device.kind}) cannot be moved"
            )
        self._align = bool(align)
        self.channels.emit("align_mtm", self._align)
        self._restart_if_enabled()
        return ACCEPTED

    def rotation_locked(self) -> bool:
        return self._rotation_locked

    def translation_locked(self) -> bool:
        return self._translation_locked

    def align_mtm(self) -> bool:
        return self._align

    def alignment_offset(self) -> np.ndarray:
        return self._R_offset.copy()

    def following_anchors(self) -> FollowingAnchors:
        """The anchors of the following law now (copies)."""
        return FollowingAnchors(
            self._T_camera_psm0.copy(),
            self._T_hrsv_mtm0.copy(),
            self._R_offset.copy(),
            self._scale,
            self._translation_locked,
            self._rotation_locked,
            self._jaw_s,
            self._jaw_o,
            self._ghost,
            self._jaw_sent,
            self._jaw_catching_up,
        )

    # ------------------------------------------------------------ console side
    def clutch(self, pressed: bool) -> None:
        """Console clutch pedal (dvrk.md 4.2)."""
        pressed = bool(pressed)
        if pressed == self._clutched:
            return
        self._clutched = pressed
        if self._current != ENABLED:
            return
        if pressed:
            self._clutch_in()
        else:
            self._jaw_catching_up = True
            self._set_following(False)
            if self._desired != DISABLED:
                self._enter(SETTING_ARMS_STATE)

    def _clutch_in(self) -> None:
        self._operator_was_active = self._operator_active
        self._set_following(False)
        if self._haptic:
            self.device.enter_effort_mode()
            if self._align or self._rotation_locked:
                self.device.lock_orientation(self._mtm_T()[:3, :3])
            else:
                self.device.unlock_orientation()
        self.psm.hold()

    # ------------------------------------------------------------ component
    def pre_step(self, t: float) -> None:
        """One tick of the state machine (called by the simulation)."""
        if self._desired == DISABLED and self._current != DISABLED:
            self._enter(DISABLED)
            return
        if self._current in (ALIGNING_MTM, ENABLED):
            if not self._arms_ok(t):
                return
        state = self._current
        if state == DISABLED:
            if self._desired in (ENABLED, ALIGNING_MTM):
                self._enter(SETTING_ARMS_STATE)
        elif state == SETTING_ARMS_STATE:
            self._run_setting_arms(t)
        elif state == ALIGNING_MTM:
            self._run_aligning(t)
        else:
            self._run_enabled()

    def snapshot(self) -> TeleopPSMState:
        inp = self.device.input()
        return TeleopPSMState(
            name=self.name,
            mtm=self.mtm_name,
            psm=self.psm_name,
            current_state=self._current,
            desired_state=self._desired,
            following=self._following,
            scale=self._scale,
            rotation_locked=self._rotation_locked,
            translation_locked=self._translation_locked,
            align_mtm=self._align,
            alignment_offset=self._R_offset.copy(),
            selected=self.selected,
            clutched=self._clutched,
            T_hrsv_mtm=None if inp is None else inp.T_hrsv_tip,
        )

    # ------------------------------------------------------------ internals
    def _mtm_T(self) -> np.ndarray:
        inp = self.device.input()
        return np.eye(4) if inp is None else inp.T_hrsv_tip

    def _enter(self, state: str) -> None:
        previous = self._current
        self._current = state
        self._entered_at = self._now()
        if state != ENABLED:
            self._set_following(False)
        if state == DISABLED:
            if previous in (ALIGNING_MTM, ENABLED) and self._haptic:
                self.device.hold()
        elif state == SETTING_ARMS_STATE:
            self._enter_setting_arms()
        elif state == ALIGNING_MTM:
            self._enter_aligning()
        else:
            self._enter_enabled()
        self.channels.emit("current_state", state)
        self.channels.message("status", f"state {state}", self._now())

    def _restart_if_enabled(self) -> None:
        # dvrk.md 4.2: lock_rotation(false) and set_align_MTM drop ENABLED to DISABLED; the
        # SETTING_ARMS_STATE → ALIGNING_MTM sequence runs again if still desired.
        if self._current == ENABLED:
            self._enter(DISABLED)

    def _reanchor(self) -> None:
        # dvrk.md 4.2: scale and lock changes only reset the initial poses (no jump).
        if self._current == ENABLED:
            self._store_initial_poses(reset_offset=False)

    def _arms_ok(self, t: float) -> bool:
        psm_state = self.psm.operating_state()
        if psm_state.state != "ENABLED" or not psm_state.is_homed:
            self._error(f"{self.psm_name} is not ready anymore ({psm_state.state}); disabling")
            self._set_desired(DISABLED)
            self._enter(DISABLED)
            return False
        if self.device.is_stale():
            self._error(
                f"{self.device.name}: {self.device.not_ready_reason()}; stopped following, "
                "waiting for fresh input"
            )
            self._enter(SETTING_ARMS_STATE)
            return False
        if not self.device.is_ready():
            self._error(
                f"{self.device.name} is not ready anymore: {self.device.not_ready_reason()}"
            )
            self._set_desired(DISABLED)
            self._enter(DISABLED)
            return False
        return True

    # -- SETTING_ARMS_STATE
    def _enter_setting_arms(self) -> None:
        state = self.psm.operating_state()
        if state.state != "ENABLED":
            self.psm.state_command("enable")
        if not state.is_homed and not self.psm.is_busy():
            self.psm.state_command("home")
        self.device.prepare()

    def _run_setting_arms(self, t: float) -> None:
        state = self.psm.operating_state()
        if state.state == "ENABLED" and state.is_homed and self.device.is_ready():
            self._enter(ALIGNING_MTM)
            return
        if t - self._entered_at > self.config.setting_arms_timeout:
            why = self.device.not_ready_reason() or f"{self.psm_name} is {state.state}"
            self._error(f"timed out while setting up arms state: {why}")
            self._set_desired(DISABLED)
            self._enter(DISABLED)

    # -- ALIGNING_MTM
    def _enter_aligning(self) -> None:
        jaw = self.psm.jaw.spec
        self._jaw_s, self._jaw_o = tm.jaw_mapping(
            jaw.qmax, self.config.gripper_zero, self.config.gripper_max
        )
        self._align_goal = None
        self._next_warning = self._now() + self.config.warning_interval
        self._gripper_range = [math.inf, -math.inf]
        self._roll_range = [math.inf, -math.inf]
        self._operator_active = self._operator_was_active
        self._operator_was_active = False

    def _run_aligning(self, t: float) -> None:
        inp = self.device.input()
        if inp is None:
            return
        R_psm = self.psm.setpoint_cp().rotation
        R_mtm = inp.rotation
        if self._align:
            error = so3.angle_between(R_mtm, R_psm)
            tol = self.config.start_orientation_tolerance
            if self._align_goal is None or so3.angle_between(self._align_goal[:3, :3], R_psm) > tol:
                self._send_align_goal(inp.T_hrsv_tip, R_psm)
        else:
            error = 0.0
        self._update_activity(inp.gripper, tm.roll_angle(R_psm, R_mtm))
        aligned = error <= self.config.start_orientation_tolerance
        if aligned and self._operator_active and not self.device.is_busy():
            if self._desired == ENABLED:
                self._enter(ENABLED)
            return
        if t >= self._next_warning:
            self._next_warning = t + self.config.warning_interval
            if not aligned:
                self.channels.message(
                    "warning",
                    f"unable to align MTM, angle error is {math.degrees(error):.1f} (deg)",
                    t,
                )
                if not self.device.is_busy():
                    self._align_goal = None  # the MTM stopped short: send the goal again
            elif not self._operator_active:
                self.channels.message("warning", "pinch/twist MTM gripper a bit", t)

    def _send_align_goal(self, T_hrsv_mtm: np.ndarray, R_psm: np.ndarray) -> None:
        goal = T_hrsv_mtm.copy()
        goal[:3, :3] = R_psm
        self._align_goal = goal
        result = self.device.move_cp(goal)
        if not result:
            self.channels.message(
                "warning", f"MTM alignment refused: {result.message}", self._now()
            )

    def _update_activity(self, gripper: float, roll: float) -> None:
        if self._operator_active:
            return
        g, r = self._gripper_range, self._roll_range
        g[0], g[1] = min(g[0], gripper), max(g[1], gripper)
        r[0], r[1] = min(r[0], roll), max(r[1], roll)
        self._operator_active = tm.operator_active(
            g[1] - g[0],
            r[1] - r[0],
            self.config.start_gripper_threshold,
            self.config.start_roll_threshold,
        )

    # -- ENABLED
    def _store_initial_poses(self, reset_offset: bool) -> None:
        self._T_hrsv_mtm0 = self._mtm_T().copy()
        self._T_camera_psm0 = self.psm.setpoint_cp().T.copy()
        if reset_offset:
            self._R_offset = tm.alignment_offset(
                self._T_hrsv_mtm0[:3, :3], self._T_camera_psm0[:3, :3]
            )

    def _enter_enabled(self) -> None:
        self._store_initial_poses(reset_offset=True)
        jaw_setpoint = float(self.psm.jaw.setpoint_js().position[0])
        self._ghost = (jaw_setpoint - self._jaw_o) / self._jaw_s
        self._jaw_sent = math.nan
        if self._haptic:
            self.device.enter_effort_mode()
            if self._rotation_locked:
                self.device.lock_orientation(self._T_hrsv_mtm0[:3, :3])
            else:
                self.device.unlock_orientation()
        if self._clutched:
            self._clutch_in()
        else:
            self._set_following(True)

    def _run_enabled(self) -> None:
        inp = self.device.input()
        if not self._following or inp is None:
            return
        if _ROW is not None and self._follow_compiled(inp):
            return
        goal = tm.follow_pose(
            self._T_camera_psm0,
            self._T_hrsv_mtm0,
            inp.T_hrsv_tip,
            self._R_offset,
            self._scale,
            translation_locked=self._translation_locked,
            rotation_locked=self._rotation_locked,
        )
        twist = tm.follow_twist(
            inp.twist_hrsv_tip,
            self._scale,
            use_linear=self.config.use_mtm_linear_velocity,
            use_angular=self.config.use_mtm_angular_velocity,
            translation_locked=self._translation_locked,
            rotation_locked=self._rotation_locked,
        )
        # The goal is a proper pose by construction (measured MTM rotation · offset): the
        # arm does not check it again at 1 kHz; its own checks (IK, limits, twist) stay.
        self.psm._servo_cp_checked(goal, twist=twist)
        if not self._ignore_jaw:
            self._follow_jaw(inp.gripper)

    def _follow_compiled(self, inp) -> bool:
        """:meth:`_run_enabled` in one compiled call (``teleop_row.follow_tick``): True when
        it gave the answer, applied as the Python path below applies it; False for that
        path to run (nothing changed): the PSM not ready for Cartesian control, or a goal
        ``servo_cp`` has no compiled answer for (its refusal and message are Python's)."""
        psm = self.psm
        cp = getattr(psm, "_cp", None)  # (servo_cp's compiled law, sim/arms.py)
        if cp is None or psm._not_ready(cartesian=True):
            return False
        c, spec = self.config, psm.jaw.spec
        flags = self._row_flags
        flags[0] = self._scale
        flags[1] = c.use_mtm_linear_velocity
        flags[2] = c.use_mtm_angular_velocity
        flags[3] = self._translation_locked
        flags[4] = self._rotation_locked
        jaw = self._row_jaw
        jaw[:11] = (self._ghost, inp.gripper, self._jaw_catching_up, c.jaw_rate,
                    c.jaw_rate_after_clutch, self._dt, self._jaw_s, self._jaw_o, spec.qmin,
                    spec.qmax, tm.JAW_CATCH_UP_TOLERANCE)  # fmt: skip
        q, _, J = psm._measured_kinematics(jacobian=True)
        constants, bound, q_out, qd_out = cp
        if not _ROW.follow_tick(
            *constants, psm._T_base_reference(), self._T_camera_psm0, self._T_hrsv_mtm0,
            inp.T_hrsv_tip, self._R_offset, inp.twist_hrsv_tip, flags, q, J, psm._qmin,
            psm._qmax, bound, q_out, qd_out, jaw,
        ):  # fmt: skip
            return False
        psm._servo_position(q_out, qd_out)  # (copied into the servo's references)
        if not self._ignore_jaw:
            self._ghost, self._jaw_catching_up, angle = float(jaw[0]), bool(jaw[2]), float(jaw[11])
            if angle != self._jaw_sent:  # the jaw servo keeps its setpoint: send changes only
                self._jaw_sent = angle
                if math.isfinite(angle):  # (clamped to the jaw's limits by follow_jaw)
                    psm.jaw._servo_jp_checked(angle)
                else:
                    psm.jaw.servo_jp(angle)  # (refused, with the jaw's message)
        return True

    def _follow_jaw(self, gripper: float) -> None:
        c, spec = self.config, self.psm.jaw.spec
        ghost, catching_up, jaw = tm.follow_jaw(
            self._ghost,
            gripper,
            self._jaw_catching_up,
            rate=c.jaw_rate,
            rate_after_clutch=c.jaw_rate_after_clutch,
            dt=self._dt,
            jaw_scale=self._jaw_s,
            jaw_offset=self._jaw_o,
            jaw_min=spec.qmin,
            jaw_max=spec.qmax,
        )
        self._ghost, self._jaw_catching_up, jaw = float(ghost), bool(catching_up), float(jaw)
        if jaw != self._jaw_sent:  # the jaw servo keeps its setpoint: send changes only
            self._jaw_sent = jaw
            self.psm.jaw.servo_jp(jaw)

    # ------------------------------------------------------------ state
    #: The settings changed by commands (scale, locks, alignment), the state machine,
    #: selection, the alignment watch and the anchors and jaw mapping while following.
    _STATE = (
        "_scale",
        "_rotation_locked",
        "_translation_locked",
        "_align",
        "_haptic",
        "_ignore_jaw",
        "_current",
        "_desired",
        "_entered_at",
        "_following",
        "_clutched",
        "selected",
        "_align_goal",
        "_next_warning",
        "_gripper_range",
        "_roll_range",
        "_operator_active",
        "_operator_was_active",
        "_T_camera_psm0",
        "_T_hrsv_mtm0",
        "_R_offset",
        "_jaw_s",
        "_jaw_o",
        "_ghost",
        "_jaw_catching_up",
        "_jaw_sent",
    )

    def get_state(self) -> dict:
        """The teleoperation's state (:data:`_STATE`), deep-copied."""
        return capture(self, self._STATE)

    def set_state(self, state: dict) -> None:
        restore(self, state, self._STATE)
