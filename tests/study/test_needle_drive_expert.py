"""The scripted expert of needle driving (``study/experts.py``, ``do_needle_drive``): an
expert drawn from the expert profile picks the needle out of its park with PSM2, hands it
to PSM1's needle-driver grip and drives it through the pad's marks, every grasp by
friction, the attempt scored by the task's own session."""

from davinci_sim.study.experts import expert_attempts
from davinci_sim.tasks import load_task


def test_an_expert_drives_the_needle_through_the_marks():
    (row,) = expert_attempts(load_task("needle_drive"), subjects=1, repetitions=1, seed=9001)
    assert row["finished"]
    assert (row["passes"], row["missed_targets"], row["drops"]) == (1, 0, 0)
    assert row["entry_error"] < 0.001 and row["exit_error"] < 0.001
    assert row["tissue_trauma"] < 0.001
    assert row["instrument_collisions"] == 0
