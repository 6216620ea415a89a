"""The scripted experts' stage (``study/experts.py: build_stage``): on a robot whose
kinematics are off (``SceneConfig.joint_errors``, the AccelNet challenge's perturbation) an
expert corrects by the tips it sees and still hands the needle over; a two-handed task file
of the user's gets its stage."""

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


def test_a_two_handed_task_file_of_the_users_gets_its_stage(tmp_path):
    """``scripts/expert_reference.py --exercise FILE`` of a two-handed kind: the stage is
    built from the task itself (a file's name is not a shipped task's)."""
    import dataclasses

    from davinci_sim.tasks import save_task

    task = dataclasses.replace(load_task("needle_pickup"), name="my_needle", lift_height=0.015)
    save_task(task, tmp_path / "my_needle.yaml")
    mine = load_task(str(tmp_path / "my_needle.yaml"))
    stage = experts.build_stage(mine)
    try:
        assert stage.session.task.name == "my_needle"
        assert stage.session.task.lift_height == 0.015
    finally:
        stage.sim.close()
