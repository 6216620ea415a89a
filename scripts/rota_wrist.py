#!/usr/bin/env python
"""How Rota's control trainees turned the tool along the Path task (issue 23, the wrist).

    PYTHONPATH=src python scripts/rota_wrist.py --clone rota [--out FILE]

The thesis says the trajectory was laid out to need wrist rotations of at least 90° about
two perpendicular axes (training.md §4). Their logs (``Training1_*_VFs.csv`` at the commit
of ``scripts/derive_rota_reference.py``, 30 Hz) give, besides the tool tip's position, its
``Forward`` vector: one axis of the tip's frame, in Unity's world. One axis shows how the
tool's direction turned, not the roll about it.

For each of the control group's 36 trials (the assisted group's are not read):

- each sample's progress: the arc-length fraction of the trajectory vertex nearest the tip
  (the trajectory file of the task, 2,600 vertices);
- the start direction: the mean ``Forward`` while the progress is at most ``START_PROGRESS``;
- at each knot of progress (0, 0.1, ..., 1) the mean ``Forward`` of the samples within half
  a knot of it, and the shortest turn from the start direction to it (a rotation vector).

The turns are mapped into our world by the rotation that places their trajectory there
(``scripts/rota_path_task.py``: their post-processing's right-handed z-up axes, then
``TURN_DEG`` about the vertical), so that the tool turns relative to the path as theirs
did. Their endoscope's position is found from the log's ``FromCamera`` (the tip's distance
to it, solved by least squares: residual ~1 µm); its orientation is not logged, but the
line of sight from it to the path is nearly square to the path's long axis (~99°): their
path runs across their view, as ``rota_path`` is placed across ours.

Writes ``docs/study/rota_path/wrist.json``: the mean turn per knot (rad, our world axes),
its angle's mean and SD over trials (deg), and each trial's largest turn from its start.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
from pathlib import Path

import numpy as np

from davinci_sim.geometry.se3 import rot_z

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs/study/rota_path/wrist.json"
KNOTS = np.linspace(0.0, 1.0, 11)
#: The samples before the tool leaves the start: progress at most this fraction.
START_PROGRESS = 0.02


def unity_to_ours(turn_deg: float) -> np.ndarray:
    """(3, 3) their Unity world axes to ours: x' = −x, y' = −z, z' = y (their
    post-processing's right-handed z-up frame, a reflection), then ``turn_deg`` about the
    vertical (the placement of ``scripts/rota_path_task.py``)."""
    reflect = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    return rot_z(math.radians(turn_deg)) @ reflect


def shortest_turn(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The rotation vector (axis · angle, rad) of the shortest turn from unit ``a`` to ``b``."""
    axis = np.cross(a, b)
    s = np.linalg.norm(axis)
    angle = np.arctan2(s, float(np.dot(a, b)))
    return np.zeros(3) if s < 1e-12 else axis / s * angle


def camera_position(p: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, float]:
    """The point whose distances to the points ``p`` (k, 3) are ``d`` (k,), least squares
    (‖p‖² − 2 p·c + ‖c‖² = d², linear in c and ‖c‖²), and the largest residual."""
    A = np.column_stack([-2.0 * p, np.ones(len(p))])
    x, *_ = np.linalg.lstsq(A, d**2 - np.sum(p * p, axis=1), rcond=None)
    return x[:3], float(np.abs(np.linalg.norm(p - x[:3], axis=1) - d).max())


def sight_angle(camera: np.ndarray, trajectory: np.ndarray) -> float:
    """The angle (deg) between the line of sight from ``camera`` to the centre of the
    trajectory's box and its start-to-end axis (Unity's axes, both)."""
    sight = (trajectory.min(axis=0) + trajectory.max(axis=0)) / 2 - camera
    axis = trajectory[-1] - trajectory[0]
    cos = sight @ axis / (np.linalg.norm(sight) * np.linalg.norm(axis))
    return float(np.degrees(np.arccos(cos)))


def trial_turns(log_csv: str, trajectory: np.ndarray, M: np.ndarray) -> dict:
    """One trial's turns: ``turn`` (knots, 3) rad in our axes (NaN where no sample is near a
    knot), ``largest`` (deg) its largest turn from the start, and its camera fit."""
    rows = list(csv.DictReader(io.StringIO(log_csv)))
    p = np.array([[float(r[f"Position{k}"]) for k in "XYZ"] for r in rows])
    forward = np.array([[float(r[f"Forward{k}"]) for k in "XYZ"] for r in rows]) @ M.T
    forward /= np.linalg.norm(forward, axis=1)[:, None]
    steps = np.linalg.norm(np.diff(trajectory, axis=0), axis=1)
    s_vertex = np.concatenate([[0.0], np.cumsum(steps)]) / steps.sum()
    nearest = np.argmin(np.linalg.norm(p[:, None, :] - trajectory[None], axis=2), axis=1)
    s = s_vertex[nearest]
    at_start = s <= START_PROGRESS
    start = forward[at_start].mean(axis=0) if at_start.any() else forward[0]
    start /= np.linalg.norm(start)
    turns = np.full((len(KNOTS), 3), np.nan)
    half = 0.5 * (KNOTS[1] - KNOTS[0])
    for k, knot in enumerate(KNOTS):
        near = np.abs(s - knot) <= half + 1e-12
        if near.any():
            mean = forward[near].mean(axis=0)
            turns[k] = shortest_turn(start, mean / np.linalg.norm(mean))
    largest = np.degrees(np.arccos(np.clip(forward @ start, -1.0, 1.0))).max()
    camera, residual = camera_position(p, np.array([float(r["FromCamera"]) for r in rows]))
    return {"turn": turns, "largest_deg": float(largest), "camera": camera,
            "camera_residual": residual}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clone", type=Path, required=True, help="a clone of their repository")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    import derive_rota_reference as reference  # (scripts/, on the path as this one runs)
    import rota_path_task as task
    unity = np.loadtxt(io.StringIO(reference.read(args.clone, task.TRAJECTORY)), delimiter=",",
                       skiprows=1)  # fmt: skip
    M = unity_to_ours(task.TURN_DEG)
    trials = []
    for subject in reference.GROUPS["control"]:
        for repetition in range(reference.DAYS * reference.TRIALS_PER_DAY):
            log = reference.read(args.clone, reference.trial_paths(subject, repetition)[0])
            trials.append({"subject": subject, "repetition": repetition,
                           **trial_turns(log, unity, M)})  # fmt: skip
    turns = np.stack([t["turn"] for t in trials])  # (trials, knots, 3)
    angles = np.degrees(np.linalg.norm(turns, axis=2))
    largest = np.array([t["largest_deg"] for t in trials])
    cameras = np.stack([t["camera"] for t in trials])
    out = {
        "source": f"github.com/{reference.REPOSITORY} at {reference.SOURCE_COMMIT}",
        "what": "the tool's turn from its start direction along the Path task, Rota's control "
        "group (36 trials); rotation vectors in our world axes (rad), the placement of "
        "scripts/rota_path_task.py",
        "knots": KNOTS.tolist(),
        "mean_turn_rad": np.round(np.nanmean(turns, axis=0), 6).tolist(),
        "turn_deg_mean": np.round(np.nanmean(angles, axis=0), 2).tolist(),
        "turn_deg_sd": np.round(np.nanstd(angles, axis=0, ddof=1), 2).tolist(),
        "largest_turn_deg": {
            "median": round(float(np.median(largest)), 1),
            "min": round(float(largest.min()), 1),
            "max": round(float(largest.max()), 1),
            "trials_at_least_90": int(np.sum(largest >= 90.0)),
            "by_trial": [
                {
                    "subject": t["subject"],
                    "repetition": t["repetition"],
                    "deg": round(t["largest_deg"], 1),
                }
                for t in trials
            ],  # fmt: skip
        },
        "camera_unity_m": np.round(cameras.mean(axis=0), 5).tolist(),
        "camera_spread_m": float(np.abs(cameras - cameras.mean(axis=0)).max()),
        "camera_residual_m": max(t["camera_residual"] for t in trials),
        # The path's long axis (start to end) against the line of sight from their
        # endoscope to the path's centre: ~90 deg is across the view.
        "sight_to_path_axis_deg": round(sight_angle(cameras.mean(axis=0), unity), 1),
    }
    args.out.write_text(json.dumps(out, indent=1) + "\n")
    print(f"largest turn: median {out['largest_turn_deg']['median']} deg "
          f"({out['largest_turn_deg']['min']}-{out['largest_turn_deg']['max']}); "
          f"mean turn per knot {out['turn_deg_mean']} -> {args.out}")  # fmt: skip


if __name__ == "__main__":
    main()
