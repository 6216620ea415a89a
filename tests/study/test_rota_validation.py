"""The committed prediction of Rota's assisted group and its comparison with the measurement
(``docs/study/rota_path/``, issue 23): the files say what their data says.

The prediction's intervals are recomputed here from the simulated subjects it stores, and
the comparison's measured figures from the derived trials, so that neither file can drift
from its source or be edited by hand."""

from __future__ import annotations

import itertools
import json
import re
from importlib.resources import files
from pathlib import Path

import numpy as np
import pytest

FOLDER = Path(__file__).resolve().parents[2] / "docs" / "study" / "rota_path"
DAYS = 4
#: The figures predicted, by the prediction's key: the derived trials' field.
METRICS = {"deviation_mm": "mean_deviation_mm", "rms_mm": "rms_deviation_mm", "time_s": "time_s"}


@pytest.fixture(scope="module")
def prediction() -> dict:
    return json.loads((FOLDER / "prediction.json").read_text())


@pytest.fixture(scope="module")
def trials() -> dict:
    path = files("davinci_sim.operators").joinpath("data/rota2023_path.json")
    return json.loads(path.read_text())


def _percentiles_of_threes(table: np.ndarray) -> np.ndarray:
    """(3, DAYS): 5th, 50th, 95th percentiles of the day means of every 3 of the subjects."""
    means = [
        np.mean([table[i] for i in c], axis=0) for c in itertools.combinations(range(len(table)), 3)
    ]
    return np.percentile(np.array(means), [5, 50, 95], axis=0)


def test_the_prediction_holds_both_hypotheses_with_ordered_intervals(prediction):
    assert set(prediction["hypotheses"]) == {"base", "reliance"}
    for h in prediction["hypotheses"].values():
        assert 0.9 <= h["finished"] <= 1.0  # (the unfinished are excluded and counted)
        for metric in METRICS:
            for key in ("assisted", "control", "assisted_minus_control"):
                cells = np.array(h[metric][key])
                assert cells.shape == (DAYS, 3)
                assert np.all(cells[:, 0] <= cells[:, 1]) and np.all(cells[:, 1] <= cells[:, 2])


def test_the_prediction_intervals_are_those_of_its_simulated_subjects(prediction):
    for h in prediction["hypotheses"].values():
        for metric in METRICS:
            for group in ("assisted", "control"):
                table = np.array(h[metric]["subjects"][group])
                assert table.shape == (prediction["subjects"], DAYS)
                expected = _percentiles_of_threes(table).T
                np.testing.assert_allclose(h[metric][group], expected, atol=2e-3)


def _measured(trials, group, field) -> np.ndarray:
    subjects = trials["groups"][group]
    return np.array(
        [
            np.mean(
                [
                    np.mean(
                        [t[field] for t in trials["trials"] if t["subject"] == s and t["day"] == d]
                    )
                    for s in subjects
                ]
            )
            for d in range(1, DAYS + 1)
        ]
    )


def test_the_validation_table_is_the_measured_data_against_the_prediction(prediction, trials):
    text = (FOLDER / "validation.md").read_text()
    assert set(trials["groups"]) == {"control", "assisted"}
    assert trials["withheld"] == []
    got = {
        m: {g: _measured(trials, g, field) for g in ("control", "assisted")}
        for m, field in METRICS.items()
    }
    dev, time = got["deviation_mm"], got["time_s"]
    for d in range(DAYS):
        row = (
            f"| {d + 1} | {dev['control'][d]:.2f} | {dev['assisted'][d]:.2f} | "
            f"{time['control'][d]:.1f} | {time['assisted'][d]:.1f} |"
        )
        assert row in text
    for name, h in prediction["hypotheses"].items():
        hits = 0
        for metric, of in got.items():
            for key, value in (
                ("assisted", of["assisted"]),
                ("assisted_minus_control", of["assisted"] - of["control"]),
            ):
                lo, hi = np.array(h[metric][key])[:, 0], np.array(h[metric][key])[:, 2]
                hits += int(np.sum((lo <= value) & (value <= hi)))
        title = re.search(rf"## Hypothesis `{name}`: (\d+) of (\d+) cells", text)
        assert title is not None and (int(title[1]), int(title[2])) == (hits, 2 * 3 * DAYS)
