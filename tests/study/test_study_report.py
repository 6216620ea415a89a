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
