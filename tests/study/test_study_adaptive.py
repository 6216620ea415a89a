"""Adaptive conditions in the study (issue 12, item 4): each subject's trial j runs with the
B the rule gives from that subject's earlier trials in the condition; the rows say which B
ran and agree with the pure rule applied to their own errors; resume keeps working."""

from __future__ import annotations

import json

import pytest

from davinci_sim.haptics.adaptive import AdaptiveRule, B_schedule, fading_B
from davinci_sim.haptics.kinds import fixture_params
from davinci_sim.study import StudyConfig, plan_trials, run_study
from davinci_sim.study.adaptive import histories, ready, resolve, rounds
from davinci_sim.study.report import TIMING_COLUMNS, write_outputs

AAN = {"type": "adaptive", "name": "aan", "mode": "assist_as_needed", "B0": 20.0, "G_max": 5.0,
       "target": 0.0005, "gain": 20000.0, "max_step": 8.0, "window": 2}  # fmt: skip
FADING = {"type": "adaptive", "name": "fade", "mode": "fading", "B0": 40.0, "G_max": 5.0,
          "zero_at": 3}  # fmt: skip


def _config(task, **kw):
    return StudyConfig(conditions=(AAN, FADING), n_subjects=2, n_repetitions=3, task=task,
                       seed=3, workers=1, **kw)  # fmt: skip


@pytest.fixture(scope="module")
def adaptive_study(short_task):
    return run_study(_config(short_task), progress=False)


def _block(rows, subject, name):
    return sorted(
        (r for r in rows if r["subject"] == subject and r["condition_name"] == name),
        key=lambda r: r["repetition"],
    )


def test_each_trial_runs_with_the_B_of_the_rule_on_its_subjects_earlier_rows(adaptive_study):
    rows = adaptive_study.rows
    assert all(r is not None for r in rows) and len(rows) == 12
    aan = AdaptiveRule.of(fixture_params(adaptive_study.config.conditions[0]))
    changed = False
    for s in range(2):
        block = _block(rows, s, "aan")
        errors = [r["deviation_error"] for r in block]
        want = B_schedule(errors[:-1], aan)
        assert [r["B"] for r in block] == pytest.approx(want, abs=0, rel=0)
        assert [json.loads(r["fixture"])["B"] for r in block] == [r["B"] for r in block]
        assert all(r["G_max"] == 5.0 for r in block)
        changed |= len(set(want)) > 1
        fade = _block(rows, s, "fade")
        assert [r["B"] for r in fade] == [40.0, 20.0, 0.0]  # 0 at the declared repetition
        assert [r["B"] for r in fade] == [fading_B(j, AdaptiveRule.of(FADING)) for j in (1, 2, 3)]
        assert "now B=0 N·s/m" in fade[-1]["law"]
    assert changed  # the trainees' errors moved B (not a rule that never acts)
    assert all(r["finished"] for r in rows)


def test_rounds_wait_for_the_history_and_nothing_else(short_task):
    specs = plan_trials(_config(short_task))
    hist = histories(specs)
    rows = [None] * len(specs)
    now = [i for i, s in enumerate(specs) if ready(s, hist[i], rows)]
    # Round 1: every fading trial, and the first repetition of each assist-as-needed block.
    assert sorted((specs[i].fixture["name"], specs[i].repetition) for i in now) == sorted(
        [("fade", r) for r in (1, 2, 3)] * 2 + [("aan", 1)] * 2
    )
    # The estimate's rounds are the runner's: round r = repetition r + 1 of each aan block.
    of_round = rounds(specs)
    assert {i for i, r in enumerate(of_round) if r == 0} == set(now)
    assert all(of_round[i] == s.repetition - 1 for i, s in enumerate(specs)
               if s.fixture["name"] == "aan")  # fmt: skip
    assert rounds([s for s in specs if s.repetition > 1]) == [
        s.repetition - 2 if s.fixture["name"] == "aan" else 0 for s in specs if s.repetition > 1
    ]  # (resumed after the first repetitions: the rest move one round up)
    first = resolve(specs[now[0]], hist[now[0]], rows)
    assert first.B in (20.0, 40.0) and first.fixture["B"] == first.B
    # A non-adaptive condition's spec is not touched.
    plain = plan_trials(StudyConfig(conditions=((40, 5),), task=short_task, n_subjects=1,
                                    n_repetitions=2))  # fmt: skip
    assert all(ready(s, [], [None]) and resolve(s, [], [None]) is s for s in plain)


def test_resume_gives_the_same_rows_and_the_report_is_written(adaptive_study, short_task,
                                                              tmp_path):  # fmt: skip
    rows = adaptive_study.rows
    specs = plan_trials(_config(short_task))
    # An interruption after round 1 and one trial of round 2.
    kept = {i: rows[i] for i, s in enumerate(specs)
            if s.fixture["mode"] == "fading" or s.repetition == 1}  # fmt: skip
    j = next(i for i, s in enumerate(specs) if s.fixture["name"] == "aan" and s.repetition == 2)
    kept[j] = rows[j]
    again = run_study(_config(short_task), progress=False, done=kept)
    assert again.resumed == len(kept)

    def strip(r):
        return {k: v for k, v in r.items() if k not in (*TIMING_COLUMNS, "sim_time")}

    assert [strip(r) for r in again.rows] == [strip(r) for r in rows]
    write_outputs(adaptive_study, tmp_path)
    assert "aan" in (tmp_path / "report.md").read_text()
