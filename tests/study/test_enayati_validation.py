"""The committed prediction of Enayati et al. 2016's guidance effect and its comparison with
their tables (``docs/study/enayati2016/``, issue 23): the files say what their data says.

The prediction's figures are recomputed here from the simulated subjects it stores, and the
comparison's verdicts from the prediction and the paper's printed values, so that neither
file can drift from its source or be edited by hand."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

FOLDER = Path(__file__).resolve().parents[2] / "docs" / "study" / "enayati2016"
#: Their static task: Table II (median max deviation, printed to 1 mm) and Table IV (mean
#: time, s), UC and VR (IROS 2016, pp. 4311-4316).
TABLE_II = (8.0, 4.0)
TABLE_IV = (98.9, 86.0)


@pytest.fixture(scope="module")
def prediction() -> dict:
    return json.loads((FOLDER / "prediction.json").read_text())


def test_the_population_figures_are_those_of_its_subjects(prediction):
    result = prediction["result"]
    max_mm = np.array(result["subjects"]["max_mm"])
    time_s = np.array(result["subjects"]["time_s"])
    assert max_mm.shape == time_s.shape == (prediction["subjects"], 2)
    assert prediction["subjects"] % 22 == 0 and prediction["prior_practice"] == 40
    assert result["finished"] == 1.0 and not np.isnan(max_mm).any()
    population = result["population"]
    medians = np.median(max_mm, axis=0)
    means = time_s.mean(axis=0)
    np.testing.assert_allclose(
        [population["UC_max_mm"], population["VR_max_mm"], population["max_ratio"]],
        [medians[0], medians[1], medians[1] / medians[0]],
        atol=2e-3,  # (stored at 1e-3 mm and 1e-4)
    )
    np.testing.assert_allclose(
        [population["UC_time_s"], population["VR_time_s"], population["time_ratio"]],
        [means[0], means[1], means[1] / means[0]],
        atol=2e-3,
    )
    for key, (lo, mid, hi) in result["interval"].items():
        assert lo <= mid <= hi, key


def test_the_validation_table_is_the_paper_against_the_prediction(prediction):
    text = (FOLDER / "validation.md").read_text()
    interval = prediction["result"]["interval"]
    for label, key, (uc, vr), half in (
        ("median max deviation", "max_ratio", TABLE_II, 0.5),
        ("mean time", "time_ratio", TABLE_IV, 0.05),
    ):
        lo, mid, hi = interval[key]
        m_lo, m_hi = (vr - half) / (uc + half), (vr + half) / (uc - half)
        hit = lo <= m_hi and m_lo <= hi
        row = (
            f"| {label} | [{lo:.3f}, {hi:.3f}] ({mid:.3f}) | {vr / uc:.3f} "
            f"({m_lo:.3f}–{m_hi:.3f}) | {'hit' if hit else '**miss**'} |"
        )
        assert row in text, row


def test_the_prediction_was_committed_before_the_comparison():
    """The commit that added the prediction is an ancestor of the one that added the
    comparison, and not the same commit (git history, when the tests run in a clone)."""
    import subprocess

    def git(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run(["git", *args], capture_output=True, text=True, cwd=FOLDER)

    def added(name: str) -> str:
        out = git("log", "--diff-filter=A", "--format=%H", "--", name).stdout.split()
        return out[-1] if out else ""

    prediction, comparison = added("prediction.md"), added("validation.md")
    if not prediction or not comparison:
        pytest.skip("no git history of docs/study/enayati2016 here")
    assert prediction != comparison
    assert git("merge-base", "--is-ancestor", prediction, comparison).returncode == 0
