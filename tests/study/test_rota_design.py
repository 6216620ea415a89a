"""Rota's protocol as a study design: a control group on the first condition every day, an
assisted group on one condition a day, the practice count running on through the days; and
the report's groups-by-day figures."""

from __future__ import annotations

import numpy as np
import pytest

from davinci_sim.study.config import StudyConfig, StudyError, plan_trials
from davinci_sim.study.days import day_figures, days_section


def test_the_groups_do_their_conditions_day_by_day():
    config = StudyConfig(task="rota_path", design="rota", n_subjects=4, n_repetitions=3)
    assert [c["name"] for c in config.conditions][:2] == ["control", "assisted x1"]
    specs = plan_trials(config)
    assert len(specs) == config.n_trials == 4 * 4 * 3
    for s in range(4):
        mine = [t for t in specs if t.subject == s]
        assert [t.order for t in mine] == [d for d in (1, 2, 3, 4) for _ in range(3)]
        assert [t.practice for t in mine] == list(range(1, 13))  # (practice runs on)
        days = [t.condition for t in mine]
        assert days == ([0] * 12 if s % 2 == 0 else [d for d in (1, 2, 3, 4) for _ in range(3)])
    assisted = [t for t in specs if t.subject == 1 and t.order == 4]
    assert {t.fixture.get("assistance") for t in assisted} == {0.25}


@pytest.mark.parametrize("kwargs", [{"conditions": [{"type": "none", "name": "control"}]},
                                    {"retention": 2}])  # fmt: skip
def test_the_design_needs_days_and_no_retention(kwargs):
    with pytest.raises(StudyError, match="rota design"):
        StudyConfig(task="rota_path", design="rota", n_subjects=2, n_repetitions=1, **kwargs)


def rows():
    """Two subjects a group, two days, two trials a day: deviation = subject + day (mm)."""
    out = []
    for s in range(4):
        for day in (1, 2):
            for k in range(2):
                out.append({"subject": s, "condition": 0 if s % 2 == 0 else day,
                            "condition_name": "control" if s % 2 == 0 else f"day {day}",
                            "order": day, "completion_time": 10.0 * day + k,
                            "deviation_error": 1e-3 * (s + day)})  # fmt: skip
    out[-1]["completion_time"] = float("nan")  # (a trial without the metric is left out)
    return out


def test_each_group_per_day_is_the_mean_and_sd_of_its_subjects_means():
    figures = {(f.group, f.day): f for f in day_figures(rows(), "deviation_error")}
    control = figures[("control", 1)]  # subjects 0 and 2: 1 and 3 mm
    assert (control.mean, control.sd, control.subjects) == pytest.approx(
        (2e-3, np.sqrt(2) * 1e-3, 2)
    )
    assert figures[("assisted", 2)].mean == pytest.approx(4e-3)  # subjects 1 and 3: 3, 5 mm
    time = {(f.group, f.day): f for f in day_figures(rows(), "completion_time")}
    assert time[("assisted", 2)].mean == pytest.approx((20.5 + 20.0) / 2)  # (3's nan left out)
    text = "\n".join(days_section(rows(), None))
    assert "| 1 | 2.00 ± 1.41 (2) | 10.50 ± 0.00 (2) | day 1 | 3.00 ± 1.41 (2) |" in text


def test_a_study_names_its_population_and_the_trials_carry_it():
    config = StudyConfig(task="rota_path", design="rota", n_subjects=2, n_repetitions=1,
                         population="expert")  # fmt: skip
    assert {t.population for t in plan_trials(config)} == {"expert"}
    with pytest.raises(StudyError, match="unknown population"):
        StudyConfig(task="rota_path", n_subjects=2, n_repetitions=1, population="nobody")


def test_the_report_of_a_rota_study_tabulates_the_groups_by_day(tmp_path):
    from davinci_sim.study.report import write_outputs
    from davinci_sim.study.runner import StudyResult
    from davinci_sim.tasks.metrics import PATH_METRICS
    from davinci_sim.tasks.trainer import trainer_metrics

    config = StudyConfig(task="rota_path", design="rota", n_subjects=4, n_repetitions=2,
                         population="rota2023")  # fmt: skip
    rng = np.random.default_rng(0)
    metrics = [m.name for m in (*PATH_METRICS, *trainer_metrics())]
    rows = [{"subject": t.subject, "condition": t.condition, "condition_name": t.condition_name,
             "order": t.order, "repetition": t.repetition, "practice": t.practice,
             "block": t.block, "finished": True, "sim_time": 20.0, "wall_time": 0.5,
             **{m: float(rng.uniform(1e-3, 3e-3)) for m in metrics},
             "completion_time": 20.0 - t.practice} for t in plan_trials(config)]  # fmt: skip
    paths = write_outputs(StudyResult(config, rows, 1.0), tmp_path)
    report = (tmp_path / "report.md").read_text()
    assert "Rota's two-group design: 4 subjects × 4 day(s)" in report
    assert "## Groups by day" in report and "## Statistical tests" not in report
    assert "| 4 | " in report and "assisted x0.25" in report
    # (the method section says which trainees ran and how they were made: here the fitted)
    assert "Population `rota2023`" in report and "fitted to the control group" in report
    assert "1.0 mm" not in report.split("## Synthetic trainees")[1].split("##")[0]
    # (the real groups' table beside the simulated one: their control group's day 1 as
    # training.md §4 gives it, 2.80 mm and 29.4 s; the assisted group's days 1 and 4)
    measured = report.split("Measured (Rota's dVRK-console study")[1]
    assert "| 1 | 2.80 ± 0.76 (3) | 29.37 ± 7.98 (3) | their day 1 | 2.70 ± 0.42 (3) |" in measured
    assert "| their day 4 | 1.99 ± 0.14 (3) | 27.81 ± 5.24 (3) |" in measured
    assert all(p.exists() for p in paths)
