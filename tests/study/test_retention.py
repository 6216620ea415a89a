"""Retention blocks (the fixture off after each practice block), the between-subject
design, the trainee mechanisms in the plan, and the report's retention section."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats as sps

from davinci_sim.study import StudyConfig, plan_trials, run_study
from davinci_sim.study.config import StudyError
from davinci_sim.study.report import write_outputs
from davinci_sim.study.stats import kruskal, pairwise_mannwhitney


def test_plan_puts_a_retention_block_after_each_practice_block():
    cfg = StudyConfig(n_subjects=2, n_repetitions=3, retention=2)
    specs = plan_trials(cfg)
    assert cfg.n_trials == len(specs) == 2 * 4 * (3 + 2)
    for s in range(2):
        mine = [x for x in specs if x.subject == s]
        assert [x.practice for x in mine] == list(range(1, 21))  # j runs on through them
        for block in range(1, 5):
            run = [x for x in mine if x.order == block]
            assert [x.block for x in run] == ["practice"] * 3 + ["retention"] * 2
            assert len({x.condition for x in run}) == 1
            assert [x.repetition for x in run] == [1, 2, 3, 1, 2]
            practised = run[0].fixture
            for x in run[3:]:  # the fixture off, the practised condition named
                assert x.fixture["type"] == "none"
                assert x.condition_name == practised["name"]
    assert len({x.key for x in specs}) == len(specs)  # retention noise is its own
    # Without retention, the plan is the one before retention blocks existed.
    plain = plan_trials(StudyConfig(n_subjects=2, n_repetitions=3))
    assert all(x.block == "practice" and len(x.key) == 4 for x in plain)
    assert [x.practice for x in plain] == [(x.order - 1) * 3 + x.repetition for x in plain]


def test_between_design_gives_each_subject_one_condition():
    cfg = StudyConfig(n_subjects=6, n_repetitions=2, retention=1, design="between")
    specs = plan_trials(cfg)
    assert cfg.n_trials == len(specs) == 6 * 3
    for s in range(6):
        assert {x.condition for x in specs if x.subject == s} == {s % 4}


def test_reliance_counts_guided_practice_less_for_the_own_correction():
    """Own-correction count: 1 + the earlier trials' steps (1 unguided, 0.36 at G_max = 8)."""
    cfg = StudyConfig(conditions=((0, 0), (60, 8)), n_subjects=1, n_repetitions=2,
                      retention=1, order="fixed", mechanisms=("reliance",))  # fmt: skip
    own = [x.own_practice for x in plan_trials(cfg)]
    # B=0: 1, 2, retention 3; B=60: 4, 4.36, retention 4.72.
    assert own == pytest.approx([1, 2, 3, 4, 4.36, 4.72])
    assert all(x.own_practice is None for x in plan_trials(StudyConfig(n_subjects=1)))


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("retention", -1, "retention"),
        ("design", "mixed", "design"),
        ("mechanisms", ("grip",), "mechanisms"),
    ],  # fmt: skip
)
def test_bad_retention_settings_are_refused(field, value, match):
    with pytest.raises(StudyError, match=match):
        StudyConfig(**{field: value})


def test_independent_group_tests_match_scipy():
    table = np.array([[1.0, np.nan], [2.0, np.nan], [3.5, np.nan],
                      [np.nan, 4.0], [np.nan, 5.0], [np.nan, 6.0]])  # fmt: skip
    h = kruskal(table)
    ref = sps.kruskal([1.0, 2.0, 3.5], [4.0, 5.0, 6.0])
    assert (h.statistic, h.pvalue) == pytest.approx((ref.statistic, ref.pvalue))
    (pair,) = pairwise_mannwhitney(table)
    ref = sps.mannwhitneyu([1.0, 2.0, 3.5], [4.0, 5.0, 6.0], alternative="two-sided")
    assert (pair.statistic, pair.pvalue, pair.p_holm) == pytest.approx(
        (ref.statistic, ref.pvalue, ref.pvalue)
    )
    assert pair.median_difference == pytest.approx(2.0 - 5.0)
    assert math.isnan(kruskal(table[:, :1]).pvalue)  # one group: no test


def test_small_study_with_a_retention_block(short_task, tmp_path):
    """2 subjects × 4 conditions × (1 practice + 1 retention), mechanisms on: a row per
    trial with its block, no guidance force in retention, the report's section and figure."""
    cfg = StudyConfig(n_subjects=2, n_repetitions=1, retention=1, task=short_task, seed=3,
                      mechanisms=("reliance", "stiffening"))  # fmt: skip
    result = run_study(cfg, progress=False)
    rows = result.rows
    assert len(rows) == 2 * 4 * 2
    assert [r["block"] for r in rows[:4]] == ["practice", "retention"] * 2
    for r in rows:
        assert r["finished"]
        assert r["mechanisms"] == "reliance+stiffening"
        if r["block"] == "retention":
            assert r["peak_force"] == 0.0  # the fixture is off
            assert r["law"] == "no guidance"
        elif r["B"] > 0:
            assert r["peak_force"] > 0
    paths = write_outputs(result, tmp_path)
    assert tmp_path / "fig10_retention.png" in paths
    assert (tmp_path / "fig10_retention.png").stat().st_size > 10_000
    report = (tmp_path / "report.md").read_text()
    for text in ("## Retention", "Design: within subjects", "### retention deviation error",
                 "Friedman", "reliance on guidance", "arm stiffening",
                 "### What the retention block shows"):  # fmt: skip
        assert text in report
    header = (tmp_path / "trials.csv").read_text().splitlines()[0].split(",")
    assert "block" in header and "own_practice" in header


def test_between_design_report_uses_independent_groups():
    """Constructed rows of a between-subject study (4 subjects, 2 conditions): the section
    says which design ran, uses Kruskal-Wallis / Mann-Whitney, and names the practised
    condition whose retention deviation is lowest (subjects 0, 2 practised B=0: 2 mm;
    subjects 1, 3 practised B=40: 3 and 4 mm)."""
    from davinci_sim.study import StudyResult
    from davinci_sim.study.retention import retention_section

    cfg = StudyConfig(n_subjects=4, n_repetitions=1, retention=1, design="between",
                      conditions=((0, 0), (40, 5)))  # fmt: skip
    rows = []
    for s in range(4):
        c = s % 2
        for block, dev in (("practice", 0.001), ("retention", 0.002 + 0.001 * c * (s // 2 + 1))):
            rows.append({"subject": s, "condition": c, "block": block, "repetition": 1,
                         "finished": True, "deviation_error": dev,
                         "completion_time": 10.0 + s})  # fmt: skip
    text = "\n".join(retention_section(StudyResult(cfg, rows, 1.0), ["B=0", "B=40"]))
    assert "Design: between subjects" in text
    assert "Mann-Whitney" in text and "| B=0 vs B=40 | -1.5 |" in text
    assert "lowest mean deviation followed practice with B=0 (2 mm)" in text
    assert "| B=40 | 1 | 3.5 ± 0.5 |" in text
    assert retention_section(StudyResult(StudyConfig(n_subjects=1), [], 1.0), []) == []
