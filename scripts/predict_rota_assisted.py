#!/usr/bin/env python
"""Predict Rota's assisted group from trainees fitted on the control group only (issue 23,
step 4): ``docs/study/rota_path/prediction.{json,md}``, committed before the assisted
group's figures are derived from the data.

    PYTHONPATH=src python scripts/predict_rota_assisted.py [--subjects 12] [--workers 2]

Runs the rota design on ``rota_path`` (``davinci-sim study --task rota_path --design rota``)
with the population fitted to the control group (``rota2023``), ``--subjects`` simulated
subjects per group, once per hypothesis (:data:`HYPOTHESES`). Per group and day, a
subject's figure is its mean over the day's 3 finished trials (all of theirs finished): the
seed's eq. 8 deviation and their RMS deviation, mm, and the trial time, s. The real groups
have 3 subjects each, so the prediction of a group's day mean is the distribution of the
mean of 3 simulated subjects: every combination of 3 of the simulated group's subjects, its
5th and 95th percentiles the 90 % interval; of the assisted minus control difference, every
pair of such combinations.
"""

from __future__ import annotations

import argparse
import itertools
import json
import subprocess
from pathlib import Path

import numpy as np

import davinci_sim  # noqa: F401  (sets MUJOCO_GL)
from davinci_sim.operators import params
from davinci_sim.study.config import StudyConfig
from davinci_sim.study.days import group_of
from davinci_sim.study.runner import run_study

FOLDER = Path(__file__).resolve().parent.parent / "docs" / "study" / "rota_path"
#: The hypotheses predicted, by name: the trainee mechanisms switched on
#: (``operators.params.Mechanisms``). ``base`` is the primary prediction; ``reliance`` the
#: one declared alternative (the guidance hypothesis). Arm stiffening is not run: its
#: threshold (3 N) is the fixture's cap, so it never acts here.
HYPOTHESES = {"base": (), "reliance": ("reliance",)}
#: The figures predicted: the seed's eq. 8 (the fit's), their own RMS metric, the time.
METRICS = {
    "deviation_mm": ("deviation_error", 1e3),
    "rms_mm": ("deviation_rms", 1e3),
    "time_s": ("completion_time", 1.0),
}
LABELS = {"deviation_mm": "deviation (mm)", "rms_mm": "RMS deviation (mm)", "time_s": "time (s)"}
GROUP_SIZE, DAYS, SEED = 3, 4, 2027
TIMEOUT = 150.0  # (s: as the fit's, no trial cut short)


def subject_days(rows: list[dict]) -> dict:
    """{group: {metric: (subjects, DAYS) array of each subject's day means}}."""
    out: dict = {}
    for group in ("control", "assisted"):
        mine = [r for r in rows if group_of(r) == group and r["finished"]]  # (theirs all did)
        subjects = sorted({int(r["subject"]) for r in mine})
        out[group] = {}
        for name, (metric, scale) in METRICS.items():
            table = np.full((len(subjects), DAYS), np.nan)
            for i, s in enumerate(subjects):
                for d in range(1, DAYS + 1):
                    v = [
                        scale * float(r[metric])
                        for r in mine
                        if int(r["subject"]) == s and int(r["order"]) == d
                    ]
                    table[i, d - 1] = np.mean(v) if v else np.nan
            out[group][name] = table
    return out


def group_means(table: np.ndarray) -> np.ndarray:
    """(combinations, DAYS): the day means of every group of GROUP_SIZE simulated subjects."""
    combos = list(itertools.combinations(range(len(table)), GROUP_SIZE))
    return np.stack([np.nanmean(table[list(c)], axis=0) for c in combos])


def interval(samples: np.ndarray) -> list[list[float]]:
    """Per day: [5th percentile, median, 95th percentile] of ``samples`` (k, DAYS)."""
    q = np.nanpercentile(samples, [5, 50, 95], axis=0)
    return [[round(float(x), 3) for x in q[:, d]] for d in range(samples.shape[1])]


def predict(mechanisms: tuple[str, ...], subjects: int, workers: int) -> dict:
    config = StudyConfig(  # (the task's conditions: control, then the assisted days)
        conditions=None,
        n_subjects=2 * subjects,
        n_repetitions=GROUP_SIZE,
        task="rota_path",
        design="rota",
        workers=workers,
        population="rota2023",
        seed=SEED,
        mechanisms=mechanisms,
        timeout=TIMEOUT,
    )
    rows = run_study(config, progress=False).rows
    tables = subject_days(rows)
    out: dict = {"finished": float(np.mean([r["finished"] for r in rows]))}
    for name in METRICS:
        control = group_means(tables["control"][name])
        assisted = group_means(tables["assisted"][name])
        difference = (assisted[:, None, :] - control[None, :, :]).reshape(-1, DAYS)
        out[name] = {
            "assisted": interval(assisted),
            "control": interval(control),
            "assisted_minus_control": interval(difference),
            "assisted_population_mean": [
                round(float(x), 3) for x in tables["assisted"][name].mean(axis=0)
            ],
            "subjects": {g: np.round(tables[g][name], 3).tolist() for g in tables},
        }
    return out


def markdown(prediction: dict) -> str:
    p = params.ROTA2023
    L = [
        "# Rota's assisted group, predicted (issue 23, step 4)",
        "",
        "Written by `scripts/predict_rota_assisted.py` **before** the assisted group's "
        "figures were derived from the data (`git log` shows this file's commit before "
        "the one that adds them). Nothing of the assisted group was read to make it.",
        "",
        f"- **Trainees:** population `rota2023`, fitted to the control group's 36 trials "
        f"only (`scripts/fit_rota_trainees.py`): noise median k = {p.noise_median:.4g}, "
        f"practised speed {1e3 * p.speed_median:.3g} mm/s, novice excess E = "
        f"{p.excess_median:.3g}, learning exponent uniform "
        f"{p.exponent_range[0]:.3g}–{p.exponent_range[1]:.3g}.",
        f"- **Simulated:** the rota design on `rota_path`, {prediction['subjects']} "
        f"subjects per group (seed {prediction['seed']}, not the fit's), 4 days x 3 trials; "
        "assisted: their fixture (viscous 15 N·s/m + elastic 0.8 N, 2 mm thresholds, sum "
        "capped at 3 N) at 1.0, 0.75, 0.5, 0.25 of full force on days 1–4.",
        "- **A group's figure:** the mean over its 3 subjects of each subject's mean over "
        "the day's 3 trials (deviation: the seed's eq. 8, mm; RMS deviation: their "
        "metric, mm; time: s). Interval: the 5th "
        "and 95th percentiles of that figure over every group of 3 simulated subjects "
        "(the real groups' size); the difference: over every pair of such groups.",
        "- **Hit:** the measured group figure inside the 90 % interval. Every cell is "
        "reported, misses included; nothing is refitted on the assisted group.",
        "- **Hypotheses:** `base` (primary: the fitted trainees as they are) and "
        "`reliance` (declared alternative: the guidance hypothesis, "
        "`operators.params.Mechanisms`). Arm stiffening is not run: its 3 N threshold is "
        "the fixture's cap.",
        "",
    ]
    for name, h in prediction["hypotheses"].items():
        L += [f"## Hypothesis `{name}` (finished {100 * h['finished']:.0f} % of trials)", ""]
        L += [
            "| figure | " + " | ".join(f"day {d + 1}" for d in range(DAYS)) + " |",
            "|---|" + "---|" * DAYS,
        ]
        for metric, label in LABELS.items():
            for key, what in (
                ("assisted", "assisted"),
                ("control", "control"),
                ("assisted_minus_control", "assisted − control"),
            ):
                cells = [f"{mid:.2f} [{lo:.2f}, {hi:.2f}]" for lo, mid, hi in h[metric][key]]
                L.append(f"| {what} {label} | " + " | ".join(cells) + " |")
        L.append("")
    return "\n".join(L)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subjects", type=int, default=12, help="simulated per group")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    head = subprocess.run(
        ["git", "rev-parse", "HEAD"],
        capture_output=True,
        text=True,
        cwd=FOLDER.parent.parent.parent,
    ).stdout.strip()
    prediction = {
        "profile": repr(params.ROTA2023),
        "subjects": args.subjects,
        "seed": SEED,
        "code_commit": head,
        "hypotheses": {},
    }
    for name, mechanisms in HYPOTHESES.items():
        prediction["hypotheses"][name] = predict(mechanisms, args.subjects, args.workers)
        print(name, "done", flush=True)
    FOLDER.mkdir(parents=True, exist_ok=True)
    (FOLDER / "prediction.json").write_text(json.dumps(prediction, indent=1) + "\n")
    (FOLDER / "prediction.md").write_text(markdown(prediction) + "\n")
    print(markdown(prediction))


if __name__ == "__main__":
    main()
