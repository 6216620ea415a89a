#!/usr/bin/env python
"""What turning the wrist changes for the fitted trainees in Rota's Path task (issue 23).

    PYTHONPATH=src python scripts/rota_wrist_effect.py [--subjects 12] [--workers 2]

The fit (``scripts/fit_rota_trainees.py``) was made on ``rota_path`` before the task had its
carried torus and the wrist's turns (``carry``: :mod:`davinci_sim.tasks.carry`). This runs
the fit's simulated control group (the fitted profile ``ROTA2023``, the fit's population
seed, 12 unassisted trials each, 3 a day for 4 days) twice: on the task as it is, the
trainees turning the MTM's handle as their plan goes (:mod:`davinci_sim.operators.wrist`),
and on the same task without its ``carry``. Writes ``docs/study/rota_path/wrist_effect.json``:
per day, the mean deviation (the seed's eq. 8, mm) and time (s) of both runs, and the
largest change of any trial.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
import yaml
from fit_rota_trainees import DAYS, SEED, TRIALS_PER_DAY, control_rows

from davinci_sim.operators import params
from davinci_sim.tasks import load_task

OUT = Path(__file__).resolve().parents[1] / "docs/study/rota_path/wrist_effect.json"


def by_day(rows: list[dict]) -> dict:
    out = {}
    for day in range(1, DAYS + 1):
        of_day = [r for r in rows if (r["repetition"] - 1) // TRIALS_PER_DAY + 1 == day]
        out[day] = {
            "deviation_mm": round(1e3 * float(np.mean([r["deviation_error"] for r in of_day])), 4),
            "time_s": round(float(np.mean([r["completion_time"] for r in of_day])), 3),
        }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subjects", type=int, default=12)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    data = load_task("rota_path").to_dict()
    if "carry" not in data:
        raise SystemExit("rota_path has no carry section: nothing to compare")
    data.pop("carry")
    with tempfile.TemporaryDirectory() as folder:
        bare = Path(folder) / "rota_path_bare.yaml"
        bare.write_text(yaml.safe_dump({**data, "name": "rota_path_bare"}, sort_keys=False))
        runs = {
            name: control_rows(params.ROTA2023, args.subjects, args.workers, SEED, task)
            for name, task in (("turning", "rota_path"), ("bare", str(bare)))
        }
    key = ("subject", "repetition")
    pairs = {tuple(r[k] for k in key): r for r in runs["bare"]}
    dev, dt = [], []
    for r in runs["turning"]:
        b = pairs[tuple(r[k] for k in key)]
        dev.append(r["deviation_error"] / b["deviation_error"] - 1.0)
        dt.append(r["completion_time"] - b["completion_time"])
    out = {
        "what": "the fitted control group (ROTA2023, population seed of the fit) on rota_path "
        "with the wrist turning and without the task's carry",
        "subjects": args.subjects,
        "finished": {n: int(sum(r["finished"] for r in rows)) for n, rows in runs.items()},
        "per_day": {n: by_day(rows) for n, rows in runs.items()},
        "largest_deviation_change": round(float(np.max(np.abs(dev))), 5),
        "largest_time_change_s": round(float(np.max(np.abs(dt))), 4),
    }
    args.out.write_text(json.dumps(out, indent=1) + "\n")
    for day in range(1, DAYS + 1):
        t, b = out["per_day"]["turning"][day], out["per_day"]["bare"][day]
        print(f"day {day}: deviation {t['deviation_mm']:.3f} mm (bare {b['deviation_mm']:.3f}), "
              f"time {t['time_s']:.2f} s (bare {b['time_s']:.2f})")  # fmt: skip
    print(f"largest change of a trial: deviation {100 * out['largest_deviation_change']:.2f} %, "
          f"time {out['largest_time_change_s']} s -> {args.out}")  # fmt: skip


if __name__ == "__main__":
    main()
