#!/usr/bin/env python
"""The spreads of the fitted trainees against Rota's control group (issue 23, step 3).

    PYTHONPATH=src python scripts/rota_spreads.py [--subjects 36] [--out FILE]

Two spreads, each for the mean deviation (the seed's eq. 8) and the trial time, computed on
the logarithms (both are positive and their spreads grow with their level):

- **between subjects**: the SD of the subjects' mean log over their 12 trials;
- **within a subject**: the residual SD of the two-way model ``log x = subject + day + e``
  (what is left of a trial once its subject's level and its day's are taken out).

Measured: the control group's 36 trials in ``operators/data/rota2023_path.json`` (3
subjects; the assisted group is not read). Simulated: ``--subjects`` trainees of the fitted
profile (``params.ROTA2023``, or it with ``--pace-spread``) doing the control group's 12
unassisted ``rota_path`` trials (seed 31, not the fit's). Three subjects pin a
between-subject spread poorly, so each measured figure is placed in the distribution of the
same figure computed on every triple of simulated subjects (its percentile: how often three
simulated subjects spread less). A figure outside the 5th-95th percentiles is a spread the
model gets wrong; one inside is one the data cannot tell from the model's. The last row is
how the deviation goes with the time from trial to trial within a subject (the slope of the
residuals' logs: the speed-accuracy trade-off the trials show).
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
from importlib.resources import files
from pathlib import Path

import numpy as np
from fit_rota_trainees import DAYS, TRIALS_PER_DAY, control_rows

from davinci_sim.operators import params

#: Not the fit's seed: other subjects than the ones it was fitted on.
SEED = 31
MEASURES = ("deviation_mm", "time_s")
#: Each measure's field in the data file.
FIELDS = {"deviation_mm": "mean_deviation_mm", "time_s": "time_s"}


def residuals(x: np.ndarray, day: np.ndarray) -> np.ndarray:
    """The two-way model's residuals of ``log x`` (:func:`spreads`), flattened."""
    y = np.log(x)
    days = np.unique(day)
    day_effect = np.array([y[:, day == d].mean() for d in days]) - y.mean()
    return (y - y.mean(axis=1)[:, None] - day_effect[np.searchsorted(days, day)][None, :]).ravel()


def spreads(x: np.ndarray, day: np.ndarray) -> dict:
    """``x`` (subjects, trials) of one measure and the trials' days (trials,): the
    between-subject SD of the subjects' mean log and the within-subject residual SD of the
    two-way additive model on the logs (subject + day, :func:`residuals`)."""
    n_s, n_t = x.shape
    dof = n_s * n_t - n_s - len(np.unique(day)) + 1
    return {
        "between_sd_log": float(np.log(x).mean(axis=1).std(ddof=1)),
        "within_sd_log": float(np.sqrt((residuals(x, day) ** 2).sum() / dof)),
    }


def coupling(deviation: np.ndarray, time: np.ndarray, day: np.ndarray) -> dict:
    """Within a subject, how a trial's deviation goes with its time: the correlation of the
    residuals of their logs and the slope of the deviation's on the time's (the speed-
    accuracy trade-off seen trial to trial: -1, the deviation grows as the speed does)."""
    a, b = residuals(deviation, day), residuals(time, day)
    return {"correlation": float(np.corrcoef(a, b)[0, 1]), "slope": float((a @ b) / (b @ b))}


def measured() -> tuple[dict, np.ndarray]:
    """The control group as (measure → (3, 12) array), and the trials' days (12,)."""
    data = json.loads(
        files("davinci_sim.operators").joinpath("data/rota2023_path.json").read_text()
    )
    trials = [t for t in data["trials"] if t["group"] == "control"]
    subjects = sorted({t["subject"] for t in trials})
    out = {}
    for m in MEASURES:
        rows = []
        for s in subjects:
            own = sorted(
                (t for t in trials if t["subject"] == s), key=lambda t: (t["day"], t["trial"])
            )
            rows.append([t[FIELDS[m]] for t in own])
        out[m] = np.array(rows)
    days = np.repeat(np.arange(1, DAYS + 1), TRIALS_PER_DAY)
    return out, days


def simulated(profile: params.Profile, subjects: int, workers: int) -> dict:
    """``profile``'s control group as (measure → (subjects, 12) array)."""
    rows = control_rows(profile, subjects, workers, seed=SEED)
    ids = sorted({r["subject"] for r in rows})
    out = {m: np.full((len(ids), TRIALS_PER_DAY * DAYS), np.nan) for m in MEASURES}
    unfinished = 0
    for r in rows:
        i, j = ids.index(r["subject"]), r["repetition"] - 1
        out["deviation_mm"][i, j] = 1e3 * r["deviation_error"]
        out["time_s"][i, j] = r["completion_time"]
        unfinished += not r["finished"]
    out["unfinished"] = unfinished
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subjects", type=int, default=36)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=None, help="write the figures as JSON")
    parser.add_argument(
        "--pace-spread", type=float, default=None, help="evaluate ROTA2023 with this pace spread"
    )
    args = parser.parse_args()
    profile = params.ROTA2023
    if args.pace_spread is not None:
        profile = dataclasses.replace(profile, pace_spread=args.pace_spread)
    real, days = measured()
    sim = simulated(profile, args.subjects, args.workers)
    report: dict = {"profile": repr(profile), "simulated_subjects": args.subjects, "seed": SEED,
                    "unfinished_trials": int(sim["unfinished"]), "measures": {}}  # fmt: skip
    print(
        "| measure | spread (SD of log) | measured (3 subjects) | simulated, all "
        f"{args.subjects} | triples of simulated: 5th-95th | measured's percentile |"
    )
    print("|---|---|---|---|---|---|")
    triples = list(itertools.combinations(range(args.subjects), 3))
    for m in MEASURES:
        got = spreads(real[m], days)
        whole = spreads(sim[m], days)
        each = [spreads(sim[m][list(t)], days) for t in triples]
        out = {}
        for key in ("between_sd_log", "within_sd_log"):
            dist = np.array([e[key] for e in each])
            pct = float(100 * np.mean(dist <= got[key]))
            lo, hi = np.percentile(dist, [5, 95])
            out[key] = {"measured": got[key], "simulated": whole[key],
                        "triples_p5": float(lo), "triples_p95": float(hi),
                        "measured_percentile": pct}  # fmt: skip
            print(f"| {m} | {key.split('_')[0]} | {got[key]:.3f} | {whole[key]:.3f} | "
                  f"{lo:.3f}-{hi:.3f} | {pct:.0f} |")  # fmt: skip
        report["measures"][m] = out
    got = coupling(real["deviation_mm"], real["time_s"], days)
    whole = coupling(sim["deviation_mm"], sim["time_s"], days)
    each = np.array([coupling(sim["deviation_mm"][list(t)], sim["time_s"][list(t)], days)["slope"]
                     for t in triples])  # fmt: skip
    lo, hi = np.percentile(each, [5, 95])
    pct = float(100 * np.mean(each <= got["slope"]))
    report["coupling"] = {"measured": got, "simulated": whole, "slope_triples_p5": float(lo),
                          "slope_triples_p95": float(hi), "measured_percentile": pct}  # fmt: skip
    print(f"| log deviation on log time, within | slope | {got['slope']:.2f} "
          f"(r {got['correlation']:.2f}) | {whole['slope']:.2f} (r {whole['correlation']:.2f}) "
          f"| {lo:.2f}-{hi:.2f} | {pct:.0f} |")  # fmt: skip
    if args.out is not None:
        args.out.write_text(json.dumps(report, indent=2) + "\n")


if __name__ == "__main__":
    main()
