#!/usr/bin/env python
"""Derive per-trial figures of the Rota (2022/23) Path task from its raw logs.

    git clone https://github.com/$REPOSITORY rota    # (REPOSITORY below)
    PYTHONPATH=src python scripts/derive_rota_reference.py --clone rota

reads, at the commit that holds them (SOURCE_COMMIT), each trial's 30 Hz log
``Assessment/Evaluation/Subject<S>/Training1/Training1_<r>/Training1_<r>_VFs.csv`` and its
published evaluation ``Training1_<r>_eval.json`` (written by the thesis's
``Assessment/PostProcessingScripts/Training1/Training1_post.py``), and writes
``src/davinci_sim/operators/data/rota2023_path.json`` (or ``--out``): per trial the group,
subject, day, trial of the day, the mean deviation (the seed's eq. 8: the arithmetic mean of
the logged distance to the trajectory over the frames), its RMS (the thesis's ``avg_dist``),
the time, the frames and the share of frames with the clutch pressed. Every trial's RMS is
checked against the published ``avg_dist`` and its time against the published ``time`` to
1e-9 (abs); a mismatch stops the script and writes nothing.

Only derived numbers are shipped, with their source (repository, commit, paths); the raw
logs stay in their repository.

``--groups control`` (the default) derives the control group only (A, P, S: no guidance on
any day). The assisted group (D, I, V) is the held-out validation set of the fitted
trainees (issue 23): its figures are derived (``--groups all``) only after the prediction
made from the control group's fit is committed.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import subprocess
from pathlib import Path

import numpy as np

REPOSITORY = "alberto-rota/Enhanched-Haptic-Training-for-Robotic-Assisted-Surgery"
SOURCE_COMMIT = "c4c749d3a7d8392a3860964df545aba34999e22a"
#: The groups as the thesis's protocol assigns them (training.md §4).
GROUPS = {"control": ("A", "P", "S"), "assisted": ("D", "I", "V")}
DAYS, TRIALS_PER_DAY = 4, 3
TOLERANCE = 1e-9
OUT = Path(__file__).resolve().parents[1] / "src/davinci_sim/operators/data/rota2023_path.json"


def trial_paths(subject: str, repetition: int) -> tuple[str, str]:
    folder = f"Assessment/Evaluation/Subject{subject}/Training1/Training1_{repetition}"
    stem = f"{folder}/Training1_{repetition}"
    return f"{stem}_VFs.csv", f"{stem}_eval.json"


def read(clone: Path, path: str) -> str:
    """A file of the repository at SOURCE_COMMIT."""
    return subprocess.run(
        ["git", "-C", str(clone), "show", f"{SOURCE_COMMIT}:{path}"],
        check=True, capture_output=True, text=True,
    ).stdout  # fmt: skip


def derive(log_csv: str) -> dict:
    """The figures of one trial's log (distances in the log are metres)."""
    rows = list(csv.DictReader(io.StringIO(log_csv)))
    if not rows:
        raise ValueError("an empty log")
    d = np.array([float(r["TrajectoryGuidanceVF_dist0"]) for r in rows])
    t = np.array([float(r["Time"]) for r in rows])
    clutch = np.array([r["Clutch"].strip() == "True" for r in rows])
    assisted = np.array([r["Assisted"].strip() == "True" for r in rows])
    assistance = np.array([float(r["Assistance"]) for r in rows])
    return {
        "mean_deviation_mm": 1000.0 * float(np.mean(d)),
        # (as Training1_post.py computes avg_dist: sqrt(mean(d**2)), metres)
        "rms_deviation_m": float(np.sqrt(np.mean(d**2))),
        "time_s": float(t[-1] - t[0]),
        "frames": len(rows),
        "clutch_share": float(np.mean(clutch)),
        "assisted_share": float(np.mean(assisted)),
        # (the day's force factor as logged: the protocol's 1, 0.75, 0.5, 0.25 when assisted)
        "assistance": float(np.mean(assistance)),
    }


def trials(clone: Path, groups: list[str]) -> list[dict]:
    out = []
    for group in groups:
        for subject in GROUPS[group]:
            for repetition in range(DAYS * TRIALS_PER_DAY):
                log_path, eval_path = trial_paths(subject, repetition)
                figures = derive(read(clone, log_path))
                published = json.loads(read(clone, eval_path))
                for ours, theirs in (("rms_deviation_m", "avg_dist"), ("time_s", "time")):
                    if abs(figures[ours] - float(published[theirs])) > TOLERANCE:
                        raise SystemExit(
                            f"{log_path}: {ours} {figures[ours]!r} differs from the published "
                            f"{theirs} {published[theirs]!r} by more than {TOLERANCE}"
                        )
                if group == "control" and published["assisted"]:
                    raise SystemExit(f"{eval_path}: a control trial marked assisted")
                rms = figures.pop("rms_deviation_m")
                out.append({
                    "group": group, "subject": subject,
                    "day": repetition // TRIALS_PER_DAY + 1,
                    "trial": repetition % TRIALS_PER_DAY + 1,
                    "repetition": repetition,
                    "mean_deviation_mm": round(figures.pop("mean_deviation_mm"), 6),
                    "rms_deviation_mm": round(1000.0 * rms, 6),
                    "published_avg_dist_m": float(published["avg_dist"]),
                    "time_s": round(figures.pop("time_s"), 6),
                    **{k: round(v, 6) if isinstance(v, float) else v for k, v in figures.items()},
                })  # fmt: skip
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--clone", type=Path, required=True,
        help=f"a clone of github.com/{REPOSITORY} (with {SOURCE_COMMIT[:8]})",
    )  # fmt: skip
    parser.add_argument("--groups", choices=("control", "all"), default="control")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    groups = ["control"] if args.groups == "control" else ["control", "assisted"]
    rows = trials(args.clone, groups)
    document = {
        "what": "Per-trial figures of the Path task (Training1) of Rota's MSc thesis, "
                "Politecnico di Milano 2022/23: a dVRK surgeon console (first-generation "
                "da Vinci MTMs, stereo viewer) driving a simulated PSM, scale 0.5; "
                "derived from the 30 Hz logs by scripts/derive_rota_reference.py",
        "source": {
            "repository": f"https://github.com/{REPOSITORY}",
            "commit": SOURCE_COMMIT,
            "logs": "Assessment/Evaluation/Subject<S>/Training1/Training1_<r>/"
                    "Training1_<r>_VFs.csv",
            "published": "Training1_<r>_eval.json (avg_dist, time), by "
                         "Assessment/PostProcessingScripts/Training1/Training1_post.py",
        },
        "checked": f"rms_deviation_mm / 1000 and time_s equal the published avg_dist and time "
                   f"to {TOLERANCE} (abs) for every trial",
        "groups": {g: list(GROUPS[g]) for g in groups},
        "withheld": [] if args.groups == "all" else [
            "the assisted group (D, I, V): the held-out validation set, derived only after "
            "the prediction from the control group's fit is committed"],
        "fields": {
            "day": "training day 1-4 (repetition // 3 + 1)",
            "trial": "trial of the day 1-3",
            "mean_deviation_mm": "arithmetic mean over the frames of the logged distance "
                                 "from the tool to the trajectory (the seed's eq. 8)",
            "rms_deviation_mm": "root mean square of the same distance (the thesis's metric)",
            "time_s": "last frame's time minus the first's",
            "frames": "logged frames (30 Hz)",
            "clutch_share": "share of frames with the clutch pressed",
            "assisted_share": "share of frames with the guidance on",
            "assistance": "the logged force factor, mean over the frames (the day's, "
                          "logged for both groups; the force acts only when assisted)",
        },
        "trials": rows,
    }  # fmt: skip
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(document, indent=1) + "\n")
    print(f"{len(rows)} trials checked and written to {args.out}")


if __name__ == "__main__":
    main()
