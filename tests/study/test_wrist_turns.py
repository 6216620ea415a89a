"""A carried object's wrist turns in the study (tasks/carry.py, operators/wrist.py): the
synthetic trainees turn the MTM's handle as their plan goes along the path, and the tool
turns with it through the teleoperation."""

from __future__ import annotations

import numpy as np

from davinci_sim.geometry.so3 import rotation_from_vector, rotation_vector
from davinci_sim.study import TrialSpec
from davinci_sim.study.batch import TrialBatch


def _angle(R_a: np.ndarray, R_b: np.ndarray) -> float:
    return float(np.degrees(np.linalg.norm(rotation_vector(R_a @ R_b.T))))


def test_the_tool_turns_as_the_trainee_turns_the_handle(carry_task):
    specs = [TrialSpec(carry_task, subject=s, condition=0, B=0.0, G_max=0.0, repetition=1,
                       order=1, practice=p, seed=5, timeout=30.0)
             for s, p in ((0, 1), (1, 5))]  # fmt: skip
    batch = TrialBatch(specs)
    wrist = batch.trainee.wrist
    R_tool0 = batch.T_psm[:, :3, :3].copy()
    lag = np.zeros(len(specs))
    last = np.zeros((len(specs), 3, 3))

    def on_tick(b: TrialBatch) -> None:
        for i in np.flatnonzero(b.active):
            r = int(b.index[i])
            # the tool's turn (camera frame) against the hand's planned turn (HRSV axes:
            # the camera's)
            tool = b.T_psm[i, :3, :3] @ R_tool0[r].T
            hand = b.T_hand[i, :3, :3] @ b.R_hand0[i].T
            lag[r] = max(lag[r], _angle(tool, hand))
            last[r] = tool

    try:
        rows = batch.run(on_tick=on_tick)
    finally:
        batch._setup.sim.close()
    assert all(r["finished"] for r in rows)
    planned = _angle(rotation_from_vector(wrist.turn[-1]), np.eye(3))  # the path's (28.6 deg)
    for r in range(len(specs)):
        assert lag[r] < 3.0  # deg: the tool follows the hand's turn as it goes
        # and ends turned most of the way (a trial ends within the finish tolerance of the
        # last point, before the plan has quite got there)
        assert 0.8 * planned < _angle(last[r], np.eye(3)) < planned + 1.0
