"""PSM inverse kinematics solve time and batched forward kinematics rate.

``python benchmarks/bench_kinematics.py psm_ik_batch`` runs only the batched PSM IK case and
prints its figures without writing the results file.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from common import summary, time_each, write
from davinci_sim.kinematics.arms import load_arm
from davinci_sim.kinematics.fk import forward_kinematics
from davinci_sim.kinematics.ik import inverse_kinematics
from davinci_sim.kinematics.psm_ik import psm_ik_closed_form_batch


def _ik_workload(kin, rng, n_ik):
    """Goals (FK of random in-limit joints, insertion ≥ 70 mm) and seeds 0.02 away."""
    lo, hi = kin.chain.qmin + 0.05, kin.chain.qmax - 0.05
    lo[2] = 0.07
    Q = rng.uniform(lo, hi, size=(n_ik, 6))
    goals = forward_kinematics(kin.chain, Q)
    seeds = np.clip(Q + rng.normal(0, 0.02, Q.shape), kin.chain.qmin, kin.chain.qmax)
    return Q, goals, seeds


def psm_ik_batch_figures(kin, goals, seeds, n: int = 200, calls: int = 500) -> dict:
    """Batched closed-form PSM IK at n rows per call (the batched study engine's ~200 PSMs).

    Same goals and seeds as the scalar ``psm_ik_closed_form`` figures, cycled in batches of n,
    so ``psm_ik_batch_n200_per_row_median_us`` compares directly with
    ``psm_ik_closed_form_median_us`` (the same kernel on one row).
    """
    batches = [(goals[i : i + n], seeds[i : i + n]) for i in range(0, len(goals) - n + 1, n)]
    it = iter(range(10**9))

    def solve():
        T, S = batches[next(it) % len(batches)]
        psm_ik_closed_form_batch(kin.chain, T, S)

    s = summary(time_each(solve, calls, warmup=20), f"psm_ik_batch_n{n}")
    out = dict(s)
    out[f"psm_ik_batch_n{n}_per_row_median_us"] = s[f"psm_ik_batch_n{n}_median_us"] / n
    return out


def main(n_ik: int = 2000, n_fk: int = 1_000_000) -> None:
    kin = load_arm("PSM1")
    rng = np.random.default_rng(0)
    Q, goals, seeds = _ik_workload(kin, rng, n_ik)
    figures = {}
    for method in ("closed_form", "reference"):
        it = iter(range(10**9))
        count = n_ik if method == "closed_form" else n_ik // 4

        def solve(method=method, it=it, count=count):
            i = next(it) % count
            inverse_kinematics(kin, goals[i], seeds[i], method=method)

        figures.update(summary(time_each(solve, count, warmup=20), f"psm_ik_{method}"))
    figures.update(psm_ik_batch_figures(kin, goals, seeds))
    Qb = rng.uniform(kin.chain.qmin, kin.chain.qmax, size=(n_fk, 6))
    forward_kinematics(kin.chain, Qb[:1000])
    rates = []
    for _ in range(5):
        t0 = time.perf_counter()
        forward_kinematics(kin.chain, Qb)
        rates.append(n_fk / (time.perf_counter() - t0))
    figures["fk_batch_poses_per_s"] = float(np.median(rates))
    figures["fk_batch_size"] = n_fk
    figures["fk_single_median_us"] = summary(
        time_each(lambda: forward_kinematics(kin.chain, Q[0]), 5000), "x"
    )["x_median_us"]
    write("kinematics", figures)


if __name__ == "__main__":
    if sys.argv[1:] == ["psm_ik_batch"]:
        kin = load_arm("PSM1")
        _, goals, seeds = _ik_workload(kin, np.random.default_rng(0), 2000)
        print(psm_ik_batch_figures(kin, goals, seeds))
    else:
        main()
