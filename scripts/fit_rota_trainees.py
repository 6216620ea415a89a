#!/usr/bin/env python
"""Fit the synthetic trainees to Rota's control group (issue 23, step 3): the fitted profile.

    PYTHONPATH=src python scripts/fit_rota_trainees.py [--subjects 12] [--workers 2]

Targets: the control group's figures in ``operators/data/rota2023_path.json`` (the assisted
group is not read: it is the held-out validation set). Simulated: ``--subjects`` control
trainees doing ``rota_path`` unassisted, 3 trials a day for 4 days (the rota design's control
group), each evaluation a batch study. Three medians of the trainee profile
(``operators.params.Profile``) are fitted, one to each of three figures, coordinate by
coordinate with a secant step in log space, ``--rounds`` times:

- the noise coefficient k to the mean deviation over the 36 trials (2.57 mm);
- the practised speed to the day-4 mean time (14.8 s);
- the novice excess E to the day-1 mean time (29.4 s).

Prints each evaluation and the fit's residuals per day (deviation and time), and the
profile's values to put in ``operators.params``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
from importlib.resources import files

import numpy as np

from davinci_sim.operators import params
from davinci_sim.study.config import StudyConfig
from davinci_sim.study.runner import run_study

TRIALS_PER_DAY, DAYS = 3, 4


def measured() -> dict:
    data = json.loads(
        files("davinci_sim.operators").joinpath("data/rota2023_path.json").read_text()
    )
    trials = [t for t in data["trials"] if t["group"] == "control"]
    out = {"deviation": np.mean([t["mean_deviation_mm"] for t in trials])}
    for day in range(1, DAYS + 1):
        of_day = [t for t in trials if t["day"] == day]
        out[f"deviation_{day}"] = np.mean([t["mean_deviation_mm"] for t in of_day])
        out[f"time_{day}"] = np.mean([t["time_s"] for t in of_day])
    return out


def simulated(profile: params.Profile, subjects: int, workers: int) -> dict:
    params.POPULATIONS["fit"] = lambda n, seed=0: params.sample_subjects(n, seed, profile)
    config = StudyConfig(
        conditions=[{"type": "none", "name": "control"}], n_subjects=subjects,
        n_repetitions=TRIALS_PER_DAY * DAYS, task="rota_path", design="between",
        workers=workers, population="fit", seed=23,
    )  # fmt: skip
    rows = run_study(config, progress=False).rows
    out = {"deviation": 1e3 * np.mean([r["deviation_error"] for r in rows]),
           "finished": np.mean([r["finished"] for r in rows])}  # fmt: skip
    for day in range(1, DAYS + 1):
        of_day = [r for r in rows if (r["repetition"] - 1) // TRIALS_PER_DAY + 1 == day]
        out[f"deviation_{day}"] = 1e3 * np.mean([r["deviation_error"] for r in of_day])
        out[f"time_{day}"] = np.mean([r["completion_time"] for r in of_day])
    return out


FITS = (("noise_median", "deviation"), ("speed_median", "time_4"), ("excess_median", "time_1"))


def newton(profile, got, target, subjects: int, workers: int, steps: int, limit: float = 0.7):
    """Newton steps on the three medians at once, in log space: the Jacobian of the three
    figures' logs by forward differences (+10 % on each median), then the step that zeroes
    the linearised residual (the figures interact: a slower trainee is also more accurate)."""
    names = [n for n, _ in FITS]
    for _ in range(steps):
        y0 = np.log([got[f] for _, f in FITS])
        J = np.empty((3, 3))
        for i, name in enumerate(names):
            moved = dataclasses.replace(profile, **{name: getattr(profile, name) * 1.1})
            other = simulated(moved, subjects, workers)
            J[:, i] = (np.log([other[f] for _, f in FITS]) - y0) / math.log(1.1)
        step = np.linalg.solve(J, np.log([target[f] for _, f in FITS]) - y0)
        step = np.clip(step, -limit, limit)  # (the model is not linear: bounded steps)
        profile = dataclasses.replace(
            profile,
            **{n: getattr(profile, n) * math.exp(d) for n, d in zip(names, step, strict=True)},
        )
        got = simulated(profile, subjects, workers)
        print("newton", profile, {k: round(float(v), 3) for k, v in got.items()}, flush=True)
    return profile, got


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subjects", type=int, default=12)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--rounds", type=int, default=2, help="coordinate rounds first")
    parser.add_argument("--newton", type=int, default=0, help="then this many Newton steps")
    parser.add_argument("--start", default=None, help="noise,speed,excess medians to start from")
    parser.add_argument("--max-step", type=float, default=0.7, help="largest log step")
    args = parser.parse_args()
    target = measured()
    profile = params.NOVICE
    if args.start:
        k, v, e = (float(x) for x in args.start.split(","))
        profile = dataclasses.replace(profile, noise_median=k, speed_median=v, excess_median=e)
    got = simulated(profile, args.subjects, args.workers)
    print("start", profile, {k: round(float(v), 3) for k, v in got.items()}, flush=True)
    profile, got = newton(profile, got, target, args.subjects, args.workers, args.newton,
                          args.max_step)  # fmt: skip
    for _ in range(args.rounds):
        for name, figure in FITS:
            # (deviation grows with k; time falls with speed, grows with E)
            x0, y0 = getattr(profile, name), got[figure]
            guess = x0 * (target[figure] / y0) ** (1 if name != "speed_median" else -1)
            trial = dataclasses.replace(profile, **{name: guess})
            got1 = simulated(trial, args.subjects, args.workers)
            y1 = got1[figure]
            slope = (math.log(y1) - math.log(y0)) / (math.log(guess) - math.log(x0))
            if abs(slope) > 1e-3:
                guess = math.exp(math.log(x0) + (math.log(target[figure]) - math.log(y0)) / slope)
                profile = dataclasses.replace(profile, **{name: guess})
                got = simulated(profile, args.subjects, args.workers)
            else:
                profile, got = trial, got1
            print(name, round(guess, 5), {k: round(float(v), 3) for k, v in got.items()},
                  flush=True)  # fmt: skip
    print("\nfitted profile:", profile)
    print("| day | deviation measured (mm) | simulated | time measured (s) | simulated |")
    for day in range(1, DAYS + 1):
        print(f"| {day} | {target[f'deviation_{day}']:.2f} | {got[f'deviation_{day}']:.2f} | "
              f"{target[f'time_{day}']:.1f} | {got[f'time_{day}']:.1f} |")  # fmt: skip


if __name__ == "__main__":
    main()
