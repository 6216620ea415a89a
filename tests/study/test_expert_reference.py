"""The expert population, the reference it makes through the batch engine, and the trainer
metrics and score of batched trials against the live engine."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from davinci_sim.operators.params import sample_experts, sample_population, sample_subjects
from davinci_sim.study import run_trial
from davinci_sim.study.reference import expert_reference, expert_specs, write_reference
from davinci_sim.tasks import load_task
from davinci_sim.tasks.scoring import load_reference

TRAINER = ("instrument_collisions", "excessive_force", "out_of_view", "master_workspace",
           "drops", "missed_targets")  # fmt: skip
#: Everything but the novice excess E.
PHYSIOLOGY = ("mass", "stiffness", "damping", "delay", "tremor_amplitude", "tremor_frequency",
              "reaction_time", "learning_exponent", "speed", "noise", "crossover")  # fmt: skip


def test_experts_are_the_subjects_at_the_plateau_of_practice():
    novices, experts = sample_subjects(40, seed=3), sample_experts(40, seed=3)
    for name in PHYSIOLOGY:
        np.testing.assert_array_equal(getattr(experts, name), getattr(novices, name))
    assert np.all(experts.practice_factor(1) < 1.3)  # on the plateau from the start
    assert np.median(novices.practice_factor(1)) > 1.8
    # their first repetition is about what a novice's is after much practice
    np.testing.assert_allclose(experts.practice_factor(1), novices.practice_factor(1e6),
                               atol=0.3)  # fmt: skip
    first = sample_population("expert", 3, seed=3)
    np.testing.assert_array_equal(first.speed, experts.speed[:3])  # a prefix, as subjects
    with pytest.raises(ValueError, match="unknown population"):
        sample_population("surgeon", 3)


def test_a_reference_made_in_the_batch_engine_gives_pass_marks(short_task, tmp_path):
    """Two experts x one repetition of the short task: every metric has a mean, SD and n;
    a task file pointing at the file uses it; the live engine gives the batch's trainer
    metrics and score on the same trial."""
    data = expert_reference(short_task, subjects=2, repetitions=1)
    assert data["finished"] == data["attempts"] == 2 and data["population"] == "expert"
    for name in TRAINER:
        assert data["metrics"][name]["n"] == 2, name  # sampled by the batch engine
    assert data["metrics"]["instrument_collisions"]["mean"] == 0.0  # nothing to touch
    assert data["metrics"]["master_workspace"]["mean"] > 0.01
    path = write_reference(data, tmp_path / "short.json")
    ref = load_reference(path)
    spec = yaml.safe_load(open(short_task))
    spec["scoring"] = {"reference": str(path)}
    (tmp_path / "short.yaml").write_text(yaml.safe_dump(spec))
    task = load_task(tmp_path / "short.yaml")
    assert task.scoring.reference == ref
    marks = task.scoring.score({}).marks
    dev = ref.metrics["deviation_error"]
    assert marks["deviation_error"] == pytest.approx(dev.mean + dev.sd)

    # live against batch, trainer metrics and score (a task with this reference)
    trial = expert_specs(str(tmp_path / "short.yaml"), subjects=2, repetitions=1)[1]
    from davinci_sim.study.batch import run_batch

    batch = run_batch([trial])[0]
    live = run_trial(trial)
    assert batch["finished"] and live["finished"]
    for name in ("instrument_collisions", "drops", "missed_targets"):
        assert batch[name] == live[name] == 0, name
    assert batch["out_of_view"] == live["out_of_view"] == 0.0
    assert batch["master_workspace"] == pytest.approx(live["master_workspace"], rel=0.02)
    assert batch["excessive_force"] == live["excessive_force"] == 0.0
    assert isinstance(batch["passed"], bool) and batch["passed"] == live["passed"]
    assert batch["score"] == pytest.approx(live["score"], abs=2.0)
    assert not math.isnan(batch["score"])
