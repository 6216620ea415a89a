#!/usr/bin/env python
"""Fit the synthetic trainees to Rota's control group (issue 23, step 3): the fitted profile.

    PYTHONPATH=src python scripts/fit_rota_trainees.py [--subjects 12] [--rounds 4]

Targets: the control group's figures in ``operators/data/rota2023_path.json`` (the assisted
group is not read: it is the held-out validation set). Simulated: ``--subjects`` control
trainees doing ``rota_path`` unassisted, 3 trials a day for 4 days (the rota design's control
group), each evaluation a batch study. Four parameters of the trainee profile
(``operators.params.Profile``) are fitted, each round from one simulation:

- **the learning curve** (practised speed, novice excess E, the learning exponent's range
  scaled as a whole) to the four day-mean times. A trial's time is close to linear in its
  practice load ``factor / speed`` (the power law's ``1 + E·j^(−α)`` over the subject's
  practised speed): the round regresses the simulated day times on the simulated subjects'
  day-mean loads (``time ≈ a + L·load``), then chooses the three parameters whose loads,
  through that line, match the measured days best (least squares on relative errors, with
  a weak prior at the module table's values: :data:`PRIOR_WEIGHT`);
- **the noise median k** to the mean deviation over the 36 trials (2.57 mm), by the step
  ``k · (measured / simulated)^(1/1.3)`` (the deviation grows about as k^1.3);
- **the noise's share of the novice excess** (``Profile.noise_learning``) to the deviation's
  fall from day 1 to day 4 (measured 2.80 → 2.55 mm: they learned speed more than accuracy),
  by a secant step on r, the day-1 over day-4 deviation ratio, through this round's and the
  previous round's (share, r) (the first round: ``--previous-share``, ``--previous-ratio``).

Prints each round and the fit's residuals per day (deviation and time), and the profile's
values to put in ``operators.params``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
from importlib.resources import files

import numpy as np
from scipy.optimize import least_squares

from davinci_sim.operators import params
from davinci_sim.study.config import StudyConfig
from davinci_sim.study.runner import run_study

TRIALS_PER_DAY, DAYS, SEED = 3, 4, 23
#: A trial's simulated time limit, s: long enough that no trial is cut short (their longest
#: trial took 48 s; a cut trial would bias the day's time down).
TIMEOUT = 150.0
#: d log(deviation) / d log(k), measured on the trainees (issue 11's calibration: 1.3).
DEVIATION_PER_NOISE = 1.3
#: Weight of the weak prior at the table's learning curve (relative time error per e-fold
#: away from the table's speed, E and exponent range): four day means do not tell E from
#: the practised speed (a larger E with a faster plateau fits as well), the prior does.
PRIOR_WEIGHT = 0.05


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


def control_rows(profile: params.Profile, subjects: int, workers: int, seed: int = SEED,
                 task: str = "rota_path") -> list[dict]:  # fmt: skip
    """The study rows of ``subjects`` trainees of ``profile`` doing the control group's 12
    unassisted ``task`` trials (3 a day for 4 days), population seed ``seed``."""
    params.POPULATIONS["fit"] = lambda n, seed=0: params.sample_subjects(n, seed, profile)
    config = StudyConfig(
        conditions=[{"type": "none", "name": "control"}], n_subjects=subjects,
        n_repetitions=TRIALS_PER_DAY * DAYS, task=task, design="between",
        workers=workers, population="fit", seed=seed, timeout=TIMEOUT,
    )  # fmt: skip
    return run_study(config, progress=False).rows


def simulated(profile: params.Profile, subjects: int, workers: int) -> dict:
    rows = control_rows(profile, subjects, workers)
    out = {"deviation": 1e3 * np.mean([r["deviation_error"] for r in rows]),
           "finished": np.mean([r["finished"] for r in rows])}  # fmt: skip
    for day in range(1, DAYS + 1):
        of_day = [r for r in rows if (r["repetition"] - 1) // TRIALS_PER_DAY + 1 == day]
        out[f"deviation_{day}"] = 1e3 * np.mean([r["deviation_error"] for r in of_day])
        out[f"time_{day}"] = np.mean([r["completion_time"] for r in of_day])
    return out


def loads(profile: params.Profile, subjects: int) -> np.ndarray:
    """(DAYS,): the simulated subjects' mean practice load ``factor / speed`` (s/m) per day."""
    p = params.sample_subjects(subjects, SEED, profile)
    j = np.arange(1, TRIALS_PER_DAY * DAYS + 1)
    load = np.array([p.practice_factor(np.full(subjects, k)) / p.speed for k in j])
    return load.reshape(DAYS, TRIALS_PER_DAY, subjects).mean(axis=(1, 2))


def with_curve(profile: params.Profile, x: np.ndarray) -> params.Profile:
    """``profile`` with the learning curve's three parameters (logs of the speed median, the
    excess median and the exponent range's scale) from ``x``."""
    low, high = params.NOVICE.exponent_range
    s = math.exp(x[2])
    return dataclasses.replace(
        profile, speed_median=math.exp(x[0]), excess_median=math.exp(x[1]),
        exponent_range=(low * s, high * s),
    )  # fmt: skip


def curve_step(profile: params.Profile, got: dict, target: dict, subjects: int):
    """The learning curve's parameters for the next round (see the module docstring)."""
    t_sim = np.array([got[f"time_{d}"] for d in range(1, DAYS + 1)])
    t_meas = np.array([target[f"time_{d}"] for d in range(1, DAYS + 1)])
    L, a = np.polyfit(loads(profile, subjects), t_sim, 1)

    prior = np.log([params.NOVICE.speed_median, params.NOVICE.excess_median, 1.0])

    def residual(x):
        days = (a + L * loads(with_curve(profile, x), subjects)) / t_meas - 1.0
        return np.concatenate([days, PRIOR_WEIGHT * (x - prior)])

    scale = profile.exponent_range[1] / params.NOVICE.exponent_range[1]
    x0 = np.log([profile.speed_median, profile.excess_median, scale])
    fit = least_squares(residual, x0)
    return with_curve(profile, fit.x), (a, L)


def show(label: str, profile: params.Profile, got: dict) -> None:
    print(label, profile, {k: round(float(v), 3) for k, v in got.items()}, flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subjects", type=int, default=12)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--rounds", type=int, default=4)
    parser.add_argument("--start", default=None,
                        help="noise,speed,excess medians, exponent scale, noise share")  # fmt: skip
    parser.add_argument(
        "--previous-share",
        type=float,
        default=1.0,
        help="a noise share evaluated before (the table's: 1)",
    )
    parser.add_argument(
        "--previous-ratio", type=float, default=1.48, help="its day-1 over day-4 deviation ratio"
    )
    args = parser.parse_args()
    target = measured()
    profile = params.NOVICE
    if args.start:
        k, v, e, s, share = (float(x) for x in args.start.split(","))
        profile = with_curve(dataclasses.replace(profile, noise_median=k, noise_learning=share),
                             np.log([v, e, s]))  # fmt: skip
    got = simulated(profile, args.subjects, args.workers)
    show("start", profile, got)
    previous = (args.previous_share, args.previous_ratio)
    for round_ in range(args.rounds):
        curved, line = curve_step(profile, got, target, args.subjects)
        k = profile.noise_median * (target["deviation"] / got["deviation"]) ** (
            1 / DEVIATION_PER_NOISE
        )
        r = got["deviation_1"] / got["deviation_4"]
        r_target = target["deviation_1"] / target["deviation_4"]
        s0, r0 = previous
        s1 = profile.noise_learning
        share = s1 if abs(r - r0) < 1e-6 else s1 + (r_target - r) * (s1 - s0) / (r - r0)
        share = float(np.clip(share, 0.0, 1.0))
        previous = (s1, r)
        profile = dataclasses.replace(curved, noise_median=k, noise_learning=share)
        got = simulated(profile, args.subjects, args.workers)
        show(f"round {round_ + 1} (time = {line[0]:.2f} s + {line[1]:.4f} m x load)", profile, got)
    print("\nfitted profile:", profile)
    print("| day | deviation measured (mm) | simulated | time measured (s) | simulated |")
    for day in range(1, DAYS + 1):
        print(f"| {day} | {target[f'deviation_{day}']:.2f} | {got[f'deviation_{day}']:.2f} | "
              f"{target[f'time_{day}']:.1f} | {got[f'time_{day}']:.1f} |")  # fmt: skip


if __name__ == "__main__":
    main()
