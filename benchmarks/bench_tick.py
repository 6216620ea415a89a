"""Bare ``mj_step`` of the full-system model vs. one full control tick of the simulation."""

from __future__ import annotations

import mujoco

from common import summary, time_each, write
from davinci_sim.sim.simulation import Simulation


def main(n: int = 5000) -> None:
    sim = Simulation("full")
    for arm in sim.arms.values():
        arm.state_command("enable")
        arm.state_command("home")
    sim.run_until(lambda: all(a.is_homed() and not a.is_busy() for a in sim.arms.values()), 30)
    model, data = sim.model, sim.data
    bare = summary(time_each(lambda: mujoco.mj_step(model, data), n), "mj_step")
    tick = summary(time_each(sim.tick, n), "tick")
    figures = {**bare, **tick}
    figures["tick_over_step_ratio"] = tick["tick_median_us"] / bare["mj_step_median_us"]
    figures["tick_real_time_factor"] = 1000.0 / tick["tick_median_us"]
    figures["nq"] = int(model.nq)
    figures["nu"] = int(model.nu)
    write("tick", figures)


if __name__ == "__main__":
    main()
