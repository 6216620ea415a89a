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

FOLDER = Path(__file__).resolve().parent.parent / "docs" / "study" / "rota_path"
DAYS = 4
FIELDS = {"deviation_mm": "mean_deviation_mm", "rms_mm": "rms_deviation_mm", "time_s": "time_s"}
LABELS = {
    "deviation_mm": ("deviation", "mm"),
    "rms_mm": ("RMS deviation", "mm"),
    "time_s": ("time", "s"),
}


def measured() -> dict:
    """{metric: {"control": (DAYS,), "assisted": (DAYS,), "assisted_minus_control": ...}}."""
    data = json.loads(
        files("davinci_sim.operators").joinpath("data/rota2023_path.json").read_text()
    )
    if "assisted" not in data["groups"]:
        raise SystemExit(
            "the assisted group is not derived yet (derive_rota_reference --groups all)"
        )
    out: dict = {}
    for name, field in FIELDS.items():
        out[name] = {}
        for group, subjects in data["groups"].items():
            days = []
            for d in range(1, DAYS + 1):
                means = [
                    np.mean(
                        [t[field] for t in data["trials"] if t["subject"] == s and t["day"] == d]
                    )
                    for s in subjects
                ]
                days.append(float(np.mean(means)))
            out[name][group] = np.array(days)
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
