"""ECM teleoperation: both MTMs move the camera while the camera pedal is held.

State machine DISABLED → SETTING_ARMS_STATE → ENABLED (dvrk.md 4.3, ``/MTML_MTMR_ECM/``).
On ENABLED the MTMs go to effort mode with their orientation locked; the ECM follows the
hands (:mod:`~davinci_sim.console.camera_control`) with ``servo_jp``; a spring and viscous
friction on each hand keep the hands' relative placement; the locked MTM orientations turn
with the camera so the instruments stay aligned with the hands in the new view. Clutch: the
ECM holds; on release it re-anchors. The console switches between this and the PSM
teleoperations with the camera pedal (dvrk.md 2.3), so the PSMs hold meanwhile.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from davinci_sim.console import camera_control as cc
from davinci_sim.console import teleop_math as tm
from davinci_sim.console.teleop_base import TeleopBase
from davinci_sim.console.teleop_config import TeleopECMConfig
from davinci_sim.console.teleop_psm import COMMANDS, DISABLED, ENABLED, SETTING_ARMS_STATE
from davinci_sim.devices.device import MasterDevice
from davinci_sim.kinematics import fk
from davinci_sim.sim.arms import ECM
from davinci_sim.sim.channels import Channels
from davinci_sim.sim.state import capture, restore
from davinci_sim.sim.types import ACCEPTED, CommandResult
from davinci_sim.sim.validation import short_repr

if TYPE_CHECKING:
    from davinci_sim.sim.simulation import Simulation


@dataclass(frozen=True)
class TeleopECMState:
    """What the ECM teleoperation publishes (dvrk.md 4.3)."""

    name: str
    current_state: str
    desired_state: str
    following: bool
    scale: float
    clutched: bool


class TeleopECM(TeleopBase):
    """Camera control by ``left`` and ``right`` MTM devices; see the module docstring."""

    def __init__(
        self,
        sim: Simulation,
        left: MasterDevice,
        right: MasterDevice,
        *,
        ecm: str = "ECM",
        mtms: tuple[str, str] = ("MTML", "MTMR"),
        config: TeleopECMConfig | None = None,
    ) -> None:
        arm = sim.arms.get(ecm)
        if not isinstance(arm, ECM):
            raise KeyError(f"no ECM {ecm!r} in this simulation; arms: {sorted(sim.arms)}")
        self.sim = sim
        self.left, self.right = left, right
        self.ecm = arm
        self.name = f"{mtms[0]}_{mtms[1]}_{ecm}"
        self.config = config or TeleopECMConfig()
        self.channels = Channels(self.name)
        self._scale = self.config.scale
        self._current = DISABLED
        self._desired = DISABLED
        self._entered_at = 0.0
        self._following = False
        self._clutched = False
        self._initial: cc.HandsGeometry | None = None
        self._q0 = np.zeros(4)
        self._R_base_camera0 = np.eye(3)
        self._R_mtm0: tuple[np.ndarray, np.ndarray] = (np.eye(3), np.eye(3))
        self._friction = np.asarray(self.config.hands_friction, dtype=float)

    # ------------------------------------------------------------ API (dvrk.md 4.3)
    def state_command(self, command: str) -> CommandResult:
        """``enable`` or ``disable``."""
        desired = COMMANDS.get(command) if isinstance(command, str) else None
        if desired not in (ENABLED, DISABLED):
            return self._refuse(
                "state_command", f"unknown command {command!r}; valid: enable, disable"
            )
        if desired != self._desired:
            self._desired = desired
            self.channels.emit("desired_state", desired)
        return ACCEPTED

    def set_scale(self, scale: float) -> CommandResult:
        s = tm.as_scale(scale)
        # ]0, 1] as the PSM teleoperations' (dvrk.md 4.1: > 0, schema maximum 1.0).
        if not (0.0 < s <= 1.0):
            return self._refuse("set_scale", f"scale must be in ]0, 1], got {short_repr(scale)}")
        self._scale = s
        self.channels.emit("scale", s)
        if self._current == ENABLED and self._following:
            self._anchor()
        return ACCEPTED

    def clutch(self, pressed: bool) -> None:
        pressed = bool(pressed)
        if pressed == self._clutched:
            return
        self._clutched = pressed
        if self._current != ENABLED:
            return
        if pressed:
            self._set_following(False)
            self.ecm.hold()
            for device in (self.left, self.right):
                device.zero_wrench()
        elif self._desired != DISABLED:
            self._enter(SETTING_ARMS_STATE)

    # ------------------------------------------------------------ component
    def pre_step(self, t: float) -> None:
        if self._desired == DISABLED and self._current != DISABLED:
            self._enter(DISABLED)
            return
        if self._current == ENABLED and not self._arms_ok():
            return
        if self._current == DISABLED:
            if self._desired == ENABLED:
                self._enter(SETTING_ARMS_STATE)
        elif self._current == SETTING_ARMS_STATE:
            ecm = self.ecm.operating_state()
            if ecm.state == "ENABLED" and ecm.is_homed and self._devices_ready():
                self._enter(ENABLED)
            elif t - self._entered_at > self.config.setting_arms_timeout:
                self._error("timed out while setting up arms state")
                self._desired = DISABLED
                self._enter(DISABLED)
        elif self._following:
            self._run_following()

    def snapshot(self) -> TeleopECMState:
        return TeleopECMState(
            self.name, self._current, self._desired, self._following, self._scale, self._clutched
        )

    # ------------------------------------------------------------ internals
    def _devices_ready(self) -> bool:
        return self.left.is_ready() and self.right.is_ready()

    def _arms_ok(self) -> bool:
        ecm = self.ecm.operating_state()
        if ecm.state != "ENABLED" or not ecm.is_homed:
            self._error(f"{self.ecm.name} is not ready anymore ({ecm.state}); disabling")
        elif not self._devices_ready():
            self._error("an MTM device is not ready anymore; disabling")
        else:
            return True
        self._desired = DISABLED
        self._enter(DISABLED)
        return False

    def _enter(self, state: str) -> None:
        previous = self._current
        self._current = state
        self._entered_at = self.sim.time
        if state != ENABLED:
            self._set_following(False)
        if state == DISABLED and previous == ENABLED:
            for device in (self.left, self.right):
                device.hold()
        elif state == SETTING_ARMS_STATE:
            ecm = self.ecm.operating_state()
            if ecm.state != "ENABLED":
                self.ecm.state_command("enable")
            if not ecm.is_homed and not self.ecm.is_busy():
                self.ecm.state_command("home")
            self.left.prepare()
            self.right.prepare()
        elif state == ENABLED:
            for device in (self.left, self.right):
                device.enter_effort_mode()
                device.lock_orientation(device.input().rotation)
            if self._clutched:
                self.ecm.hold()
            else:
                self._anchor()
                self._set_following(True)
        self.channels.emit("current_state", state)
        self.channels.message("status", f"state {state}", self.sim.time)

    def _anchor(self) -> None:
        left, right = self.left.input(), self.right.input()
        try:
            self._initial = cc.hands_geometry(left.position, right.position)
        except ValueError as e:
            self._error(f"cannot use the hands' placement: {e}; disabling")
            self._desired = DISABLED
            self._enter(DISABLED)
            return
        self._q0 = self.ecm.setpoint_jp()
        self._R_base_camera0 = fk.forward_kinematics(self.ecm.chain, self._q0)[:3, :3]
        self._R_mtm0 = (left.rotation.copy(), right.rotation.copy())

    def _run_following(self) -> None:
        left, right = self.left.input(), self.right.input()
        try:
            now = cc.hands_geometry(left.position, right.position)
        except ValueError:
            return  # degenerate placement for an instant: keep the last goal
        motion = cc.camera_motion(self._initial, now, self._scale)
        q = cc.ecm_joint_goal(self._q0, motion, self.config.camera_roll_offset)
        q = np.clip(q, self.ecm.chain.qmin, self.ecm.chain.qmax)
        self.ecm.servo_jp(q)
        # Forces that keep the hands' placement.
        goal_left, goal_right = cc.hands_goals(self._initial, now)
        for device, goal, inp in ((self.left, goal_left, left), (self.right, goal_right, right)):
            force = cc.hands_force(
                goal,
                inp.position,
                inp.twist_hrsv_tip[:3],
                self.config.hands_stiffness,
                self._friction,
                self.config.haptic_feedback_ratio,
            )
            device.servo_cf(np.concatenate([force, np.zeros(3)]))
        # The view turned by dR (in the initial camera frame): the instruments, fixed in the
        # world, turned by dRᵀ in the view, and so do the locked MTM orientations.
        R_base_camera = fk.forward_kinematics(self.ecm.chain, q)[:3, :3]
        dR = self._R_base_camera0.T @ R_base_camera
        for device, R0 in zip((self.left, self.right), self._R_mtm0, strict=True):
            device.lock_orientation(dR.T @ R0)

    # ------------------------------------------------------------ state
    #: The scale, the state machine and the hands' and arm's anchors while following.
    _STATE = (
        "_scale",
        "_current",
        "_desired",
        "_entered_at",
        "_following",
        "_clutched",
        "_initial",
        "_q0",
        "_R_base_camera0",
        "_R_mtm0",
    )

    def get_state(self) -> dict:
        return capture(self, self._STATE)

    def set_state(self, state: dict) -> None:
        restore(self, state, self._STATE)
