#!/usr/bin/env python
"""Compare the committed prediction of Rota's assisted group with its measured figures
(issue 23, step 4): ``docs/study/rota_path/validation.md``.

    PYTHONPATH=src python scripts/compare_rota_prediction.py

Reads ``docs/study/rota_path/prediction.json`` (``scripts/predict_rota_assisted.py``) and
the measured trials in ``operators/data/rota2023_path.json`` (derived with ``--groups all``
after the prediction's commit). A measured group's figure per day: the mean over its 3
subjects of each subject's mean over the day's trials, as the prediction defines it. Every
cell is a hit when the measured figure lies in the predicted 90 % interval.
"""

from __future__ import annotations

import json
import subprocess
from importlib.resources import files
from pathlib import Path

import numpy as np

from davinci_sim.study.days import day_figures, measured_rows

FOLDER = Path(__file__).resolve().parent.parent / "docs" / "study" / "rota_path"
DAYS = 4
#: The prediction's figures: the study rows' metric and its scale to the figure's unit.
METRICS = {"deviation_mm": ("deviation_error", 1e3), "rms_mm": ("deviation_rms", 1e3),
           "time_s": ("completion_time", 1.0)}  # fmt: skip
LABELS = {
    "deviation_mm": ("deviation", "mm"),
    "rms_mm": ("RMS deviation", "mm"),
    "time_s": ("time", "s"),
}


def measured() -> dict:
    """{metric: {"control": (DAYS,), "assisted": (DAYS,), "assisted_minus_control": ...}}."""
    rows = measured_rows()
    if not any(r["condition"] for r in rows):
        raise SystemExit(
            "the assisted group is not derived yet (derive_rota_reference --groups all)"
        )
    out: dict = {}
    for name, (metric, scale) in METRICS.items():
        figures = day_figures(rows, metric)
        out[name] = {g: np.array([scale * f.mean for f in figures if f.group == g])
                     for g in ("control", "assisted")}  # fmt: skip
        out[name]["assisted_minus_control"] = out[name]["assisted"] - out[name]["control"]
    return out


def _log(*args: str) -> list[str]:
    out = subprocess.run(
        ["git", "log", "--format=%h %cI", *args], capture_output=True, text=True, cwd=FOLDER
    ).stdout
    return [x for x in out.split("\n") if x.strip()]


def commit_of(path: Path) -> str:
    """The commit that added ``path`` (short hash and date), or '?'."""
    lines = _log("--diff-filter=A", "--", str(path))
    return lines[-1] if lines else "?"


def last_commit_of(path: Path) -> str:
    """The last commit that changed ``path``, or 'not committed yet'."""
    lines = _log("-1", "--", str(path))
    return lines[0] if lines else "not committed yet"


def table(prediction: dict, got: dict, hypothesis: str) -> tuple[list[str], int, int]:
    h = prediction["hypotheses"][hypothesis]
    L = ["| figure | day | measured | predicted median [90 %] | hit |", "|---|---|---|---|---|"]
    hits = total = 0
    for name, (label, unit) in LABELS.items():
        for key, what in (
            ("assisted", "assisted"),
            ("assisted_minus_control", "assisted − control"),
        ):
            for d in range(DAYS):
                lo, mid, hi = h[name][key][d]
                m = float(got[name][key][d])
                hit = lo <= m <= hi
                hits, total = hits + hit, total + 1
                L.append(
                    f"| {what} {label} ({unit}) | {d + 1} | {m:.2f} | "
                    f"{mid:.2f} [{lo:.2f}, {hi:.2f}] | {'yes' if hit else '**no**'} |"
                )
    return L, hits, total


def main() -> None:
    prediction = json.loads((FOLDER / "prediction.json").read_text())
    got = measured()
    data_file = Path(str(files("davinci_sim.operators").joinpath("data/rota2023_path.json")))
    L = [
        "# Rota's assisted group: prediction against measurement (issue 23, step 4)",
        "",
        "- Prediction: `prediction.md`, first committed in "
        f"{commit_of(FOLDER / 'prediction.json')}.",
        f"- Measured: the assisted group (D, I, V) in `operators/data/rota2023_path.json`, "
        f"derived from the logs after the prediction (the file's last change: "
        f"{last_commit_of(data_file)}).",
        "- A figure: the mean over the group's 3 subjects of each subject's mean over the "
        "day's 3 trials; hit: inside the predicted 90 % interval.",
        "",
        "| day | control deviation (mm) | assisted deviation (mm) | control time (s) | "
        "assisted time (s) |",
        "|---|---|---|---|---|",
    ]
    for d in range(DAYS):
        L.append(
            f"| {d + 1} | {got['deviation_mm']['control'][d]:.2f} | "
            f"{got['deviation_mm']['assisted'][d]:.2f} | {got['time_s']['control'][d]:.1f} | "
            f"{got['time_s']['assisted'][d]:.1f} |"
        )
    for name in prediction["hypotheses"]:
        rows, hits, total = table(prediction, got, name)
        L += ["", f"## Hypothesis `{name}`: {hits} of {total} cells inside the interval", ""]
        L += rows
    text = "\n".join(L) + "\n"
    (FOLDER / "validation.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
