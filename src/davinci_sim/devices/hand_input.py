"""A person's hand on a simulated MTM, steered by a rate input: keyboard, gamepad, SpaceMouse.

Someone without a dVRK console drives a :class:`~davinci_sim.devices.SimulatedMTM` with an
input that gives velocities, not poses (keys held down, sticks, a 3-D mouse). :class:`HandInput`
is the simulation component that turns such an input into the simulated hand's target:
every tick, before the device reads the MTM, it moves the hand's target by ``v · dt`` (HRSV,
m/s) and sets the gripper, and the hand's spring-damper pulls the MTM handle along
(:mod:`davinci_sim.devices.hand`). While the hand moves freely its damping acts about the
target's own motion (the target's velocity goes with it, ``SimulatedMTM.move_hand``): a
handle moving with the hand is not held back, and it is under way ~12 ms after a key where a
hand damping it in space took ~30 ms. The MTM answers with its own dynamics and the haptic
loop's forces push back on the handle, so the tool follows the person's input through the
same device → console → teleoperation path as a real MTM, and a guidance force is felt as
the handle lagging the hand.

The wrist: an angular velocity (``command(..., angular=...)``, rad/s in HRSV) turns the
hand's target orientation; from the first turn on, the hand holds the handle's orientation
(a person who has turned the wrist keeps it there) and the teleoperation turns the tool the
same way in the camera frame (the alignment offset multiplies on the right). Before any turn
the wrist stays relaxed, as the teleoperation's alignment needs.

Safety, as a dead-man switch: a velocity holds for ``timeout`` seconds of simulated time
(a page that stops sending stops the hand); the target never leads the handle by more than
``max_lead`` (a hand pushing against a fixture or a joint limit does not wind up a spring
that would snap the tool away when released); the target stays within ``workspace`` of where
the hand took the handle; the target orientation never leads the handle's by more than
``max_turn_lead``.

HRSV axes (dvrk.md 4.2: the teleoperation maps HRSV motion to camera-frame motion of the
tool, scaled): x to the left of the image, y up, z into the scene.
"""

from __future__ import annotations

import math

import numpy as np

from davinci_sim.devices.simulated import SimulatedMTM
from davinci_sim.geometry import so3
from davinci_sim.sim.state import capture, restore
from davinci_sim.sim.types import ACCEPTED, CommandResult

#: The gripper's range, rad: squeezed (−15°) … just closed (0) … 60° open (dvrk.md 1.5,
#: 4.1 ``gripper_scaling``). Squeezing past "just closed" gives negative angles, which the
#: teleoperation maps to a jaw goal below 0 (−15° → −20°, the dVRK's close, dvrk.md 3.2):
#: the jaw's effort then saturates on what it holds instead of stopping at a goal of 0.
GRIPPER_SQUEEZED = math.radians(-15.0)
GRIPPER_RANGE = (GRIPPER_SQUEEZED, math.radians(60.0))


class HandInput:
    """Steers ``device``'s hand with velocities; see the module docstring.

    Args:
        device: the simulated MTM.
        max_speed: largest hand speed accepted, m/s.
        timeout: a velocity command holds this long, s of simulated time.
        max_lead: largest distance of the hand's target ahead of the handle, m.
        workspace: largest distance of the target from where the hand took the handle, m.
        max_turn: largest angular speed of the wrist accepted, rad/s.
        max_turn_lead: largest angle of the target orientation ahead of the handle's, rad.
        name: component name (default ``"<MTM>/hand"``).
    """

    def __init__(
        self,
        device: SimulatedMTM,
        *,
        max_speed: float = 0.25,
        timeout: float = 0.3,
        max_lead: float = 0.01,
        workspace: float = 0.15,
        max_turn: float = 2.0,
        max_turn_lead: float = 0.3,
        name: str | None = None,
    ) -> None:
        for label, value in (
            ("max_speed", max_speed),
            ("timeout", timeout),
            ("max_lead", max_lead),
            ("workspace", workspace),
            ("max_turn", max_turn),
            ("max_turn_lead", max_turn_lead),
        ):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{label} must be > 0, got {value!r}")
        self.device = device
        self.max_speed = float(max_speed)
        self.timeout = float(timeout)
        self.max_lead = float(max_lead)
        self.workspace = float(workspace)
        self.max_turn = float(max_turn)
        self.max_turn_lead = float(max_turn_lead)
        self.name = name or f"{device.mtm}/hand"
        self._holding = False
        self._origin = np.zeros(3)
        self._target = np.zeros(3)
        self._v = np.zeros(3)
        self._w = np.zeros(3)
        self._R_target: np.ndarray | None = None
        """The wrist's target orientation (HRSV); None: the wrist is relaxed."""
        self._v_until = -math.inf
        self._gripper: float | None = None
        self._time = 0.0

    # ------------------------------------------------------------ commands
    def grasp(self) -> CommandResult:
        """Take the handle where it is (the hand then holds its position until moved; the
        wrist is left to the MTM)."""
        p = self._handle_position()
        self._origin, self._target = p.copy(), p.copy()
        self._v = np.zeros(3)
        self._w = np.zeros(3)
        self._R_target = None
        self._holding = True
        # The wrist stays relaxed: the rate input moves the handle, and the teleoperation
        # aligns the MTM's orientation with the tool's (a held wrist would fight it).
        self.device.grasp(p, hold_orientation=False)
        return ACCEPTED

    def release(self) -> CommandResult:
        """Let go of the handle (the MTM holds where it is)."""
        if self._holding:
            self.device.release()
        self._holding = False
        self._v = np.zeros(3)
        self._w = np.zeros(3)
        self._R_target = None
        return ACCEPTED

    def relax_wrist(self) -> CommandResult:
        """Let the wrist go (the hand keeps the handle's position): e.g. while the
        teleoperation aligns the MTM's orientation with the tool's; the next turn takes the
        wrist again where it is."""
        if self._holding and self._R_target is not None:
            self._R_target = None
            self.device.grasp(self._target.copy(), hold_orientation=False)
        return ACCEPTED

    def command(self, velocity, gripper: float | None = None, angular=None) -> CommandResult:
        """Move the hand at ``velocity`` (3 floats, HRSV, m/s) and turn the wrist at
        ``angular`` (3 floats, HRSV, rad/s; None: no turn) for the next ``timeout``
        seconds, and set the gripper to ``gripper`` rad if given.

        The hand takes the handle first if it does not hold it. Refused, with nothing
        changed, for a velocity that is not 3 finite numbers or is faster than
        ``max_speed``, an angular velocity that is not 3 finite numbers or is faster than
        ``max_turn``, or a gripper angle outside ``GRIPPER_RANGE``.
        """
        w = np.zeros(3)
        if angular is not None:
            try:
                w = np.asarray(angular, dtype=float)
            except (TypeError, ValueError):
                return _refused(self.name, f"angular must be 3 numbers (rad/s), got {angular!r}")
            if w.shape != (3,) or not np.isfinite(w).all():
                return _refused(
                    self.name, f"angular must be 3 finite numbers (rad/s), got {angular!r}"
                )
            turn = float(np.linalg.norm(w))
            if turn > self.max_turn:
                return _refused(self.name, f"turn {turn:.3f} rad/s is over {self.max_turn} rad/s")
        try:
            v = np.asarray(velocity, dtype=float)
        except (TypeError, ValueError):
            return _refused(self.name, f"velocity must be 3 numbers (m/s), got {velocity!r}")
        if v.shape != (3,) or not np.isfinite(v).all():
            return _refused(self.name, f"velocity must be 3 finite numbers (m/s), got {velocity!r}")
        speed = float(np.linalg.norm(v))
        if speed > self.max_speed:
            return _refused(self.name, f"speed {speed:.3f} m/s is over {self.max_speed} m/s")
        if gripper is not None:
            lo, hi = GRIPPER_RANGE
            if (
                isinstance(gripper, bool)
                or not isinstance(gripper, (int, float))
                or not (lo <= gripper <= hi)
            ):
                return _refused(
                    self.name,
                    f"gripper must be an angle in [{lo}, {hi:.3f}] rad, got {gripper!r}",
                )
        if not self._holding:
            self.grasp()  # moving the input takes the handle
        self._v = v
        self._w = w
        self._v_until = self._time + self.timeout
        if gripper is not None:
            self._gripper = float(gripper)
        return ACCEPTED

    def _handle_position(self) -> np.ndarray:
        """The handle's position in HRSV, m (the device's last input, or the arm now)."""
        read = self.device.input()
        return (
            read.position if read is not None else self.device.arm.measured_cp().position
        ).copy()

    @property
    def holding(self) -> bool:
        return self._holding

    # ------------------------------------------------------------ component
    def pre_step(self, t: float) -> None:
        self._time = t
        if not self._holding:
            return
        dt = self.device.sim.dt
        if t < self._v_until:
            handle = self._handle_position()
            target = self._target + self._v * dt
            lead = target - handle
            d = float(np.linalg.norm(lead))
            free = True  # (the hand moves at the key's velocity)
            if d > self.max_lead:  # the handle is held back: the hand waits for it
                target = handle + lead * (self.max_lead / d)
                free = False
            reach = target - self._origin
            r = float(np.linalg.norm(reach))
            if r > self.workspace:
                target = self._origin + reach * (self.workspace / r)
                free = False
            # A hand moving freely moves with its target: its damping acts about the key's
            # velocity (SimulatedMTM.move_hand's), the turn's where the wrist turned. A hand
            # held back (its lead or its workspace) damps the handle's motion in space, as
            # at rest: a hand pushing on a held handle is not a spring without damping.
            velocity = np.zeros(6)
            if free:
                velocity[:3] = self._v
            self._target = target
            if self._w.any() and self._turn(dt):
                velocity[3:] = self._w
            if self._R_target is None:
                self.device.move_hand(target, velocity)
            else:
                T = np.eye(4)
                T[:3, :3], T[:3, 3] = self._R_target, target
                self.device.move_hand(T, velocity)
        if self._gripper is not None:
            self.device.squeeze(self._gripper)
            self._gripper = None

    def _turn(self, dt: float) -> bool:
        """Turn the wrist's target by ``angular·dt`` (from the handle's orientation at the
        first turn, when the wrist starts holding), unless it already leads the handle by
        ``max_turn_lead``; whether it turned."""
        read = self.device.input()
        R_handle = (read.T_hrsv_tip if read is not None else self.device.arm.measured_cp().T)[
            :3, :3
        ]
        if self._R_target is None:
            self._R_target = R_handle.copy()
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = self._R_target, self._target
            self.device.grasp(T, hold_orientation=True)
        R = so3.rotation_from_vector(self._w * dt) @ self._R_target
        if so3.angle_between(R, R_handle) <= max(
            self.max_turn_lead, so3.angle_between(self._R_target, R_handle)
        ):  # (the handle lagging further stops the target, as max_lead does)
            self._R_target = R
            return True
        return False

    def snapshot(self) -> dict:
        moving = self._time < self._v_until
        return {
            "holding": self._holding,
            "velocity": tuple(float(x) for x in (self._v if moving else np.zeros(3))),
            "angular": tuple(float(x) for x in (self._w if moving else np.zeros(3))),
            "wrist_held": self._R_target is not None,
            "target": tuple(float(x) for x in self._target),
        }

    _STATE = ("_holding", "_origin", "_target", "_v", "_w", "_R_target", "_v_until",
              "_gripper", "_time")  # fmt: skip

    def get_state(self) -> dict:
        return capture(self, self._STATE)

    def set_state(self, state: dict) -> None:
        restore(self, state, self._STATE)


def _refused(name: str, message: str) -> CommandResult:
    return CommandResult(False, f"{name}: {message}")
