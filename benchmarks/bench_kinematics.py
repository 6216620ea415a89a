"""PSM inverse kinematics solve time and batched forward kinematics rate."""

from __future__ import annotations

import time

import numpy as np

from common import summary, time_each, write
from davinci_sim.kinematics.arms import load_arm
from davinci_sim.kinematics.fk import forward_kinematics
from davinci_sim.kinematics.ik import inverse_kinematics


def main(n_ik: int = 2000, n_fk: int = 1_000_000) -> None:
    kin = load_arm("PSM1")
    rng = np.random.default_rng(0)
    lo, hi = kin.chain.qmin + 0.05, kin.chain.qmax - 0.05
    lo[2] = 0.07
    Q = rng.uniform(lo, hi, size=(n_ik, 6))
    goals = forward_kinematics(kin.chain, Q)
    seeds = np.clip(Q + rng.normal(0, 0.02, Q.shape), kin.chain.qmin, kin.chain.qmax)
    figures = {}
    for method in ("closed_form", "reference"):
        it = iter(range(10**9))
        count = n_ik if method == "closed_form" else n_ik // 4

        def solve(method=method, it=it, count=count):
            i = next(it) % count
            inverse_kinematics(kin, goals[i], seeds[i], method=method)

        figures.update(summary(time_each(solve, count, warmup=20), f"psm_ik_{method}"))
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
    main()
