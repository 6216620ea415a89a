"""The study of a needle exercise (``study/console_trial.py``, ``study/exercise_report.py``):
a synthetic trainee does it with its hands on both MTMs, through the console's
teleoperations and haptic loop; the study runs it with a fixture of the user's choice and
reports the exercise's own metrics."""

import csv
import math

import numpy as np
import pytest

from davinci_sim.haptics.path_query import closest_point
from davinci_sim.study import StudyConfig, StudyError
from davinci_sim.study.console_trial import ConsoleStreamer, console_stage
from davinci_sim.study.experts import Motor
from davinci_sim.study.trial import TrialSpec, run_trial
from davinci_sim.tasks import load_task


def test_an_expert_picks_up_and_hands_off_the_needle_through_the_mtms():
    """The study's live engine with an expert of the population: both instruments move only
    because the hands moved the MTMs (the trainee sends no PSM command), the needle is
    lifted, handed over and held; the row has the exercise's metrics and score."""
    spec = TrialSpec(task="needle_pickup", subject=0, condition=0, seed=9001,
                     fixture={"type": "none", "name": "none"}, population="expert")  # fmt: skip
    row = run_trial(spec)
    assert row["finished"] and row["task"] == "needle_pickup"
    assert (row["handoffs"], row["drops"], row["instrument_collisions"]) == (1, 0, 0)
    assert 0.0 < row["completion_time"] < 30.0 and 0.0 < row["score"] <= 100.0
    stage = console_stage(load_task("needle_pickup"), 9001)
    for teleop in stage.teleops.values():  # (both hands on, both teleoperations following)
        assert teleop.is_following() and teleop.device.hand_target() is not None


def test_the_streamer_aims_the_hand_where_the_teleoperation_puts_the_tool():
    """A setpoint of PSM1 becomes MTMR's hand target; held there, the teleoperation brings
    the tool to it (within the hand's sub-millimetre lag), and a jaw angle becomes a squeeze
    of the MTM's gripper that the PSM's jaw follows."""
    task = load_task("needle_pickup")
    stage = console_stage(task, 9001)
    sim = stage.sim
    sim.set_state(stage.state)
    motor = Motor(speed=0.02, noise=0.0, tremor=0.0, tremor_hz=8.0, delay=0.1, reaction=0.1,
                  rng=np.random.default_rng(0))  # fmt: skip
    stream = ConsoleStreamer(sim, motor, stage.T_camera_task, stage.teleops)
    start = stream.goal["PSM1"].copy()
    goal = start[:3, 3] + [0.01, 0.0, 0.005]
    stream.glide({"PSM1": goal}, 0.5)
    stream.set_jaw("PSM1", 0.6)
    stream.wait(1.0)
    tip = stream.seen_tip("PSM1")
    assert np.linalg.norm(tip - goal) < 0.001
    assert abs(sim.arms["PSM1"].jaw.measured_js().position[0] - 0.6) < 0.02
    assert np.linalg.norm(stream.seen_tip("PSM2") - stream.goal["PSM2"][:3, 3]) < 0.001


def test_the_needle_drive_offers_guidance_along_its_drive():
    """A fixture of the user's choice acts along the drive path: the needle driver's tool
    tip turning the needle through the marks (a spring pulls a tip off it back to it);
    adaptive guidance (a path metric's) is refused."""
    task = load_task("needle_drive")
    path = task.drive_path.vertices
    # the arc of one pair: every vertex as far from the needle's centre as the grip point
    assert len(path) == 42 and np.ptp(np.linalg.norm(np.diff(path, axis=0), axis=1)) < 1e-4
    fixture = task.fixture({"type": "spring", "stiffness": 200.0})
    p = path[20] + [0.0, 0.0, 0.004]
    force = np.asarray(fixture.force(p[None], np.zeros((1, 3)))).reshape(-1)[:3]
    to_path = closest_point(task.drive_path, p[None]).point[0] - p
    assert force @ to_path > 0.99 * np.linalg.norm(force) * np.linalg.norm(to_path) > 0.0
    assert np.linalg.norm(force) == pytest.approx(200.0 * np.linalg.norm(to_path), rel=1e-6)
    with pytest.raises(Exception, match="adaptive"):
        task.check_fixture({"type": "adaptive"})


def test_a_needle_study_runs_live_and_refuses_what_it_cannot_run():
    config = StudyConfig(task="needle_drive", n_subjects=1, n_repetitions=1, engine="live",
                         conditions=({"type": "viscous", "B": 40.0, "G_max": 5.0},))  # fmt: skip
    assert config.kind == "needle_drive" and config.conditions[0]["type"] == "viscous"
    with pytest.raises(StudyError, match="live engine"):
        StudyConfig(task="needle_drive", n_subjects=1, n_repetitions=1)
    with pytest.raises(StudyError, match="mechanisms"):
        StudyConfig(task="needle_pickup", n_subjects=1, n_repetitions=1, engine="live",
                    mechanisms=("reliance",))  # fmt: skip
    with pytest.raises(StudyError, match="ring_walk exercise"):
        StudyConfig(task="ring_walk", n_subjects=1, n_repetitions=1, engine="live")


def test_the_study_command_runs_a_needle_exercise_and_reports_its_metrics(tmp_path, capsys):
    """``davinci-sim study --task needle_pickup``: the live engine by default, one row per
    trial with the exercise's columns, a report with its summary table and a figure."""
    from davinci_sim.cli import main

    out = tmp_path / "out"
    assert main(["study", "--task", "needle_pickup", "--subjects", "1", "--repetitions", "1",
                 "--population", "expert", "--seed", "9001", "--no-progress",
                 "-o", str(out)]) == 0  # fmt: skip
    assert "live engine" in capsys.readouterr().out
    (row,) = csv.DictReader(open(out / "trials.csv"))
    assert row["task"] == "needle_pickup" and row["finished"] == "True"
    assert row["handoffs"] == "1" and math.isfinite(float(row["score"]))
    report = (out / "report.md").read_text()
    assert "| condition | completion time (s) |" in report and "deviation_error" not in row
    assert (out / "scores_per_repetition.png").stat().st_size > 0
