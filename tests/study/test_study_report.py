"""The study report's labels and tests for studies other than Table I (issue 11, 1)."""

import pytest

from davinci_sim.study import StudyConfig, run_study
from davinci_sim.study.report import short_labels, write_report


def test_labels_tell_conditions_apart():
    assert short_labels([(0, 0), (40, 5)]) == ["B=0", "B=40"]
    assert short_labels([(40, 2), (40, 5)]) == ["B=40/Gmax=2", "B=40/Gmax=5"]


@pytest.fixture(scope="module")
def two_conditions(short_task, tmp_path_factory):
    config = StudyConfig(conditions=((40.0, 2.0), (40.0, 5.0)), n_subjects=3,
                         n_repetitions=1, task=short_task, workers=1, seed=2)  # fmt: skip
    path = tmp_path_factory.mktemp("report") / "report.md"
    write_report(run_study(config, progress=False), path)
    return path.read_text()


def test_two_conditions_get_the_wilcoxon_test_and_distinct_labels(two_conditions):
    text = two_conditions.split("## Statistical tests", 1)[1].split("## The seed's claims")[0]
    assert "Friedman χ²" not in text and "two-sided Wilcoxon signed-rank test of the pair" in text
    assert "| B=40/Gmax=2 vs B=40/Gmax=5 |" in text
    assert "nan" not in text.split("| pair |", 1)[0]


def test_the_report_compares_with_a_previous_run(tmp_path):
    """read_csv gives back what write_csv wrote, and the comparison section puts each
    condition's previous and new means side by side, led by what changed."""
    import csv

    from davinci_sim.study import StudyResult
    from davinci_sim.study.compare import comparison, read_csv

    config = StudyConfig(n_subjects=2, n_repetitions=1, conditions=((0, 0), (40, 5)))
    rows = [
        {"subject": s, "condition": c, "repetition": 1, "finished": True,
         "deviation_error": 0.001 * (2 - c) * (1 + s), "mean_force": 0.1 * c,
         "completion_time": 10.0 + s, "law": "as printed, B=40"}
        for s in range(2) for c in range(2)
    ]  # fmt: skip
    path = tmp_path / "trials.csv"
    with open(path, "w", newline="") as f:  # as report.write_csv writes its rows
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows({k: repr(v) if isinstance(v, float) else v for k, v in r.items()}
                    for r in rows)  # fmt: skip
    assert read_csv(path) == rows
    old = [dict(r, deviation_error=r["deviation_error"] * 2) for r in rows]
    text = "\n".join(comparison(StudyResult(config, rows, 1.0), old, "The law changed."))
    assert "## Compared with the previous run\n\nThe law changed." in text
    # B=0: the subjects' deviations are 2 and 4 mm now (mean 3), twice that before.
    assert "| B=0 | 6 → 3 (-50%) | 0 → 0 | 10.5 → 10.5 (+0%) |" in text
    assert "| B=40 | 3 → 1.5 (-50%) | 0.1 → 0.1 (+0%) |" in text
