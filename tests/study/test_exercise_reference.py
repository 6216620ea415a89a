"""The skill exercises' expert references: each exercise's scoring uses its shipped reference
(default pass marks: expert mean ± 1 SD) and gives pass/fail; a reference made again with a
tiny group has the shipped files' format; the scripted expert's reach noise is the motor
noise model's open-loop endpoint SD."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from davinci_sim.study.experts import Motor, not_measured
from davinci_sim.study.reference import exercise_reference
from davinci_sim.tasks import load_task, save_task
from davinci_sim.tasks.scoring import reference_dir

#: The exercises with a shipped expert reference (none for the ICRA peg board's variant).
EXERCISES = ("camera_targeting", "ring_walk", "needle_targeting", "needle_pickup", "needle_drive",
             "peg_transfer", "running_suture")  # fmt: skip


@pytest.mark.parametrize("name", EXERCISES)
def test_each_exercise_scores_against_its_expert_reference(name):
    task = load_task(name)
    scoring = task.scoring
    assert scoring.reference is not None, scoring.note  # made on this very task
    ref = scoring.reference
    assert ref.meta["engine"] == "scripted" and ref.meta["finished"] >= 2
    marks = {i.metric: scoring.pass_mark(i) for i in scoring.items}
    judged = {k: v for k, v in marks.items() if v is not None}
    assert judged  # the default pass marks now apply
    for item in scoring.items:
        r = ref.metrics[item.metric]
        if item.metric in not_measured(task.kind, task.name):
            assert marks[item.metric] is None  # no reference value, no mark
        elif item.pass_mark is None and math.isfinite(r.mean):
            sign = 1.0 if item.better == "lower" else -1.0
            assert marks[item.metric] == pytest.approx(r.mean + sign * r.sd)
    expert = {k: ref.metrics[k].mean for k in judged}
    assert task.score(expert)["passed"] is True
    # Worse than the mark on one metric (time to complete: 1 s past it): a fail.
    worse = dict(expert, completion_time=judged["completion_time"] + 1.0)
    assert task.score(worse)["passed"] is False
    assert task.score(expert, finished=False)["passed"] is False


def test_a_tiny_reference_has_the_shipped_format(tmp_path):
    """2 experts x 1 repetition of a one-target needle exercise, through the same
    function the script calls: the shipped file's keys, per metric mean, SD, n and unit."""
    task = load_task("needle_targeting")
    small = dataclasses.replace(task, name="needle_one", targets=task.targets[:1],
                                directions=task.directions[:1])  # fmt: skip
    path = tmp_path / "needle_one.yaml"
    save_task(small, path)
    data = exercise_reference(str(path), subjects=2, repetitions=1, seed=5)
    shipped = json.loads((reference_dir() / "needle_targeting.json").read_text())
    assert set(data) == set(shipped)
    assert set(data["metrics"]) == set(shipped["metrics"])
    assert data["attempts"] == 2 and data["finished"] == 2
    assert data["produced_by"].startswith("scripts/expert_reference.py --exercise needle_one")
    for name, entry in data["metrics"].items():
        assert set(entry) == {"mean", "sd", "n", "unit"}
        if name in not_measured("needle_targeting"):
            assert entry["n"] == 0 and entry["mean"] is None
        else:
            assert entry["n"] == 2
    assert data["metrics"]["targets_hit"]["mean"] == 1.0
    json.dumps(data)  # JSON-ready


def test_a_reach_ends_off_its_aim_by_the_open_loop_endpoint_sd():
    """noise.py: a minimum-jerk reach of amplitude A and duration T ends with an SD of
    k·A·√(2τ·(10/7)/T) per axis; with T = A/v that is the Motor's endpoint_sd."""
    from davinci_sim.operators.noise import MUSCLE_TIME_CONSTANT as tau
    from davinci_sim.operators.params import sample_experts

    motor = Motor.of(sample_experts(2, seed=1), 0, 1, 0.6, np.random.default_rng(0))
    A, v = 0.05, motor.reach_speed
    T = A / v
    assert motor.endpoint_sd(A, v) == pytest.approx(
        motor.noise * A * math.sqrt(2 * tau * (10 / 7) / T)
    )
    ends = np.array([motor.aim(np.zeros(3), [A, 0.0, 0.0]) for _ in range(4000)])
    assert ends.std(axis=0) == pytest.approx([motor.endpoint_sd(A, v)] * 3, rel=0.08)
