"""A scripted expert on a robot whose kinematics are off (``SceneConfig.joint_errors``, the
AccelNet challenge's perturbation): it corrects by the tips it sees and still picks the
needle up and hands it over."""

import numpy as np

from davinci_sim.study import experts
from davinci_sim.tasks import load_task

#: Both PSMs off by a few degrees and millimetres (within the challenge's ±5°, ±5°, ±5 mm).
ERRORS = {"PSM1": (0.044, -0.008, 0.004), "PSM2": (-0.03, 0.04, -0.003)}


def test_an_expert_sees_where_the_tools_are_and_hands_the_needle_over(monkeypatch):
    """The attempt finishes with one hand-off and no drop; the expert's corrections (its
    bias per arm: where it saw each tip minus where it sent it) are millimetres, the
    robot's error it made up for."""
    streamers = []
    init = experts.Streamer.__init__

    def kept(self, *args, **kwargs):
        init(self, *args, **kwargs)
        streamers.append(self)

    monkeypatch.setattr(experts.Streamer, "__init__", kept)
    (row,) = experts.expert_attempts(load_task("needle_pickup"), subjects=1, repetitions=1,
                                     seed=9001, joint_errors=ERRORS)  # fmt: skip
    assert row["finished"] and row["handoffs"] == 1 and row["drops"] == 0
    (stream,) = streamers
    assert stream.sees_tips
    for arm in ("PSM1", "PSM2"):
        assert np.linalg.norm(stream.bias[arm]) > 0.003  # m
