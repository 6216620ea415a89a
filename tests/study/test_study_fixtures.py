"""The study's fixtures (issue 11, items 3 and 5): the seed's law as printed by default, the
on-path ramp as a reported option, any fixture kind from a task file or the command line, in
the batch engine as in the live one, and a user's own law with the full report."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
import yaml

from davinci_sim.haptics.kinds import describe_fixture, register_fixture_kind
from davinci_sim.haptics.viscous import viscous_guidance_terms
from davinci_sim.study import StudyConfig, StudyError, plan_trials, run_study, run_trial
from davinci_sim.study.batch import TrialBatch, run_batch
from davinci_sim.study.config import parse_conditions, parse_fixture
from davinci_sim.study.report import write_outputs
from davinci_sim.study.trial import TrialSpec, load_spec_task
from davinci_sim.tasks import load_task


def _force_of_the_law(batch: TrialBatch, row: int, *, B, G_max, transition) -> np.ndarray:
    """The viscous law, evaluated here from the batch's recorded state: the tip and the
    filtered velocity the haptic loop used, moved into the task frame by hand."""
    T = batch.T_task_camera
    R, t = T[:3, :3], T[:3, 3]
    p = R @ batch.T_psm[row, :3, 3] + t
    v = R @ batch.velocity.velocity[row]
    deviation = batch.task.path.closest_point(p[None]).deviation[0]
    f = viscous_guidance_terms(v, deviation, B=B, G_max=G_max, transition=transition).force
    return R.T @ f


def test_a_default_study_trial_runs_the_law_as_printed(short_task):
    """A trial planned with default settings applies the seed's law with transition 0: the
    force the haptic loop requests is viscous_guidance_terms(..., transition=0) of the
    recorded state, and not the ramped law's while the tool is within 0.5 mm of the path."""
    config = StudyConfig(task=short_task, n_subjects=1, n_repetitions=1)
    spec = next(s for s in plan_trials(config) if s.B == 40.0)
    assert spec.fixture["transition"] == 0.0
    batch = TrialBatch([spec])
    checked = differs = 0
    for tick in range(3000):
        batch.tick()
        if tick % 10 or not batch.active[0]:
            continue
        want = _force_of_the_law(batch, 0, B=40.0, G_max=5.0, transition=0.0)
        np.testing.assert_allclose(batch.requested[0], want, atol=1e-12)
        ramped = _force_of_the_law(batch, 0, B=40.0, G_max=5.0, transition=0.0005)
        checked += np.linalg.norm(want) > 0.01
        differs += np.linalg.norm(want - ramped) > 1e-3
    batch._setup.sim.close()
    assert checked > 50 and differs > 10  # the guidance pushed, often inside the 0.5 mm ramp


def test_the_ramp_is_an_option_carried_to_the_trials_and_the_report(short_task, tmp_path):
    config = StudyConfig(conditions=((0, 0), (40, 5)), task=short_task, n_subjects=1,
                         n_repetitions=1, workers=1, timeout=0.5, transition=0.0005)  # fmt: skip
    specs = plan_trials(config)
    assert {s.fixture["transition"] for s in specs} == {0.0005}
    batch = TrialBatch([s for s in specs if s.B == 40.0])
    assert batch.fixtures[1].fixtures[0].transition == 0.0005  # the ViscousGuidance built
    batch._setup.sim.close()
    write_outputs(run_study(config, progress=False), tmp_path)
    report = (tmp_path / "report.md").read_text()
    assert "Viscous guidance, with a 0.5 mm on-path ramp." in report
    with open(tmp_path / "trials.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["law"] for r in rows if r["B"] == "40.0"] == [
        "viscous guidance, with a 0.5 mm on-path ramp: B=40 N·s/m, G_max=5 N"
    ]
    # The default says so too; a task file's own ramp is kept ("unless it asks otherwise").
    plain = StudyConfig(conditions=((40, 5),), task=short_task)
    assert "law as printed" in describe_fixture(plain.conditions[0])
    own = {"name": "ramped", "type": "viscous", "B": 40.0, "G_max": 5.0, "transition": 1e-4}
    assert StudyConfig(conditions=(own,), task=short_task).conditions[0]["transition"] == 1e-4


def _task_with_conditions(short_task: str, folder: Path, conditions: list[dict]) -> str:
    data = yaml.safe_load(Path(short_task).read_text())
    data["conditions"] = conditions
    path = folder / "spring_task.yaml"
    path.write_text(yaml.safe_dump(data))
    return str(path)


SPRING = {"name": "spring", "type": "spring", "stiffness": 600.0, "damping": 4.0,
          "max_force": 3.0}  # fmt: skip


def test_a_spring_condition_from_a_task_file_runs_in_the_batch_as_live(short_task, tmp_path):
    task = _task_with_conditions(short_task, tmp_path, [{"name": "none", "type": "none"}, SPRING])
    config = StudyConfig(task=task, n_subjects=2, n_repetitions=1, seed=5)
    assert [c["name"] for c in config.conditions] == ["none", "spring"]
    specs = [s for s in plan_trials(config) if s.fixture["type"] == "spring"]
    rows = run_batch(specs)
    for spec, row in zip(specs, rows, strict=True):
        live = run_trial(spec)
        assert row["law"] == live["law"] and row["law"].startswith("spring guidance")
        assert row["finished"] and live["finished"]
        assert row["peak_force"] > 0.05  # the spring pulled
        assert row["samples"] == pytest.approx(live["samples"], abs=30)
        assert row["completion_time"] == pytest.approx(live["completion_time"], abs=0.03)
        assert row["deviation_error"] == pytest.approx(live["deviation_error"], rel=0.1)
        assert row["peak_force"] == pytest.approx(live["peak_force"], rel=0.1)
        assert row["mean_force"] == pytest.approx(live["mean_force"], rel=0.1)


class HalfSpring:
    """A user's own law for the test: a pull of ``gain``·φ towards the path (N/m)."""

    def __init__(self, path, gain: float) -> None:
        if not gain >= 0:
            raise ValueError(f"gain must be >= 0, got {gain!r}")
        self.path, self.gain = path, gain

    def force(self, position, velocity) -> np.ndarray:
        return self.gain * self.path.closest_point(position).deviation

    @staticmethod
    def describe(params) -> str:
        return f"test pull: {params['gain']:g} N/m towards the path"


def test_a_users_own_law_plugs_in_and_gets_the_full_report(short_task, tmp_path):
    register_fixture_kind("test_pull", HalfSpring, params={"gain"},
                          describe=HalfSpring.describe)  # fmt: skip
    conditions = ({"type": "none"}, {"type": "test_pull", "gain": 400.0, "name": "pull"})
    config = StudyConfig(conditions=conditions, task=short_task, n_subjects=3,
                         n_repetitions=1, workers=1, seed=1)  # fmt: skip
    result = run_study(config, progress=False)
    paths = write_outputs(result, tmp_path)
    assert {p.name for p in paths} >= {"trials.csv", "report.md", "fig8_deviation_distribution.png"}
    assert all(p.stat().st_size > 0 for p in paths)
    by = {c: [r for r in result.rows if r["condition"] == c] for c in (0, 1)}
    assert all(r["peak_force"] == 0 for r in by[0])
    assert all(r["peak_force"] > 0 and r["law"] == "test pull: 400 N/m towards the path"
               for r in by[1])  # fmt: skip
    report = (tmp_path / "report.md").read_text()
    assert "| pull | test pull: 400 N/m towards the path |" in report
    assert "| none vs pull |" in report  # the pair's Wilcoxon test, labelled by name
    assert "Not applicable" in report  # the seed's claims are about Table I
    # The same law as an importable module:Name needs no registration.
    entry = {"type": "davinci_sim.haptics.spring:SpringGuidance", "stiffness": 100.0}
    (resolved,) = StudyConfig(conditions=(entry,), task=short_task).conditions
    assert resolved["type"] == entry["type"] and resolved["name"].startswith("davinci_sim")


def test_command_line_conditions_take_names_pairs_and_entries(short_task):
    task = load_task("seed_path")
    assert parse_conditions("B=0,40:5", task) == (dict(task.condition("B=0")), (40.0, 5.0))
    with pytest.raises(StudyError, match="condition of the task"):
        parse_conditions("B=1000", task)
    assert parse_fixture("{type: spring, stiffness: 200}") == {"type": "spring",
                                                               "stiffness": 200}  # fmt: skip
    with pytest.raises(StudyError, match="mapping with a 'type'"):
        parse_fixture("[1, 2]")
    with pytest.raises(StudyError, match="unknown fixture type"):
        StudyConfig(conditions=({"type": "magnet"},), task=short_task)
    with pytest.raises(StudyError, match="unknown keys"):
        StudyConfig(conditions=({"type": "spring", "stiffnes": 1.0},), task=short_task)
    with pytest.raises(StudyError, match="transition"):
        StudyConfig(task=short_task, transition=-1.0)


def test_a_trial_spec_keeps_b_and_gmax_for_the_viscous_law():
    spec = TrialSpec("seed_path", subject=0, condition=0, B=40.0, G_max=5.0)
    assert spec.fixture == {"type": "viscous", "B": 40.0, "G_max": 5.0, "transition": 0.0}
    other = TrialSpec("seed_path", subject=0, condition=0, fixture=SPRING)
    assert np.isnan(other.B) and other.fixture["transition"] == 0.0005  # the spring's default
    with pytest.raises(ValueError, match="contradicts"):
        TrialSpec("seed_path", subject=0, condition=0, B=20.0, G_max=5.0,
                  fixture={"type": "viscous", "B": 40.0, "G_max": 5.0})  # fmt: skip
    assert load_spec_task(spec).name == "seed_path"
