"""The tracking watch of every arm of a simulation in one compiled call per tick
(:func:`~davinci_sim.sim.arm_laws.tracking_watch`): the dVRK PID's tracking-error fault
(``arm_laws.tracking_bad`` and ``tracking_fault`` per arm, :data:`TRACKING_FAULT_TOLERANCE`
for :data:`TRACKING_FAULT_TIME`), checked on each ENABLED arm after every arm has written
its setpoints for the coming step.

The arms keep their state (``Arm._tracking_bad_since``, in their ``get_state``); the watch
gathers it into one array and writes it back, and faults an arm through the arm itself, with
the same reason as before.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from davinci_sim.sim import arm_laws as laws
from davinci_sim.sim import operating_state as ops

if TYPE_CHECKING:
    from davinci_sim.sim.arm import Arm
    from davinci_sim.sim.servo import JointServo


class TrackingWatch:
    """The watch over ``arms`` (in a fixed order) of one simulation."""

    def __init__(self, arms: list[Arm]) -> None:
        self.arms = list(arms)
        n = len(self.arms)
        self._adr = np.concatenate([a._tracking_adr for a in self.arms]).astype(np.int64)
        self._idx = np.concatenate([a._tracking_idx for a in self.arms]).astype(np.int64)
        self._tol = np.concatenate([a._tol for a in self.arms]).astype(float)
        sizes = [len(a._tracking_idx) for a in self.arms]
        self._starts = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self._watched = np.zeros(n, dtype=bool)
        self._bad_since = np.full(n, np.nan)
        self._first_bad = np.full(n, -1, dtype=np.int64)
        self._fault = np.zeros(n, dtype=bool)

    def check(self, qpos: np.ndarray, servo: JointServo, t: float) -> None:
        """One tick of the watch at simulated time ``t`` (s), with the measured joint
        positions ``qpos`` and the servo's setpoints: an arm out of tolerance for
        ``TRACKING_FAULT_TIME`` goes to FAULT (``Arm._tracking_fault``)."""
        arms, watched, since = self.arms, self._watched, self._bad_since
        for k, arm in enumerate(arms):
            watched[k] = arm._state == ops.ENABLED
            since[k] = arm._tracking_bad_since
        any_fault = laws.tracking_watch(
            qpos, self._adr, servo.q_ref, self._idx, self._tol, servo.effort_mode,
            self._starts, watched, since, float(t), self._first_bad, self._fault,
        )  # fmt: skip
        for k, arm in enumerate(arms):
            if watched[k]:
                arm._tracking_bad_since = float(since[k])
        if any_fault:
            for k in np.flatnonzero(self._fault):
                arms[k]._tracking_fault(int(self._first_bad[k]))
