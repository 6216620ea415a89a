"""Peg transfer's tick cost (:mod:`davinci_sim.tasks.peg`): the physics step of a scene with
the board and three rings (PSM1, PSM2 and the ECM) against the same scene without them and
with the board but without the noslip solver, the task's reading of the scene
(``scene_fields``: ring centres and jaw contacts), one monitored sample (state machine and
metrics) for one trial, and the pure step for 100 trials at once.

The rings rest on their pegs (contacts with pegs and board every step) while the arms hold
their homed pose. ``python benchmarks/bench_peg.py`` writes ``results/peg.json``.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402

import davinci_sim  # noqa: E402, F401  (sets MUJOCO_GL)
from common import summary, time_each, write  # noqa: E402
from davinci_sim.model import SceneConfig  # noqa: E402
from davinci_sim.sim.simulation import Simulation  # noqa: E402
from davinci_sim.tasks import load_task  # noqa: E402
from davinci_sim.tasks.base import Sample  # noqa: E402
from davinci_sim.tasks.state import TaskMonitor  # noqa: E402

SCENE = SceneConfig(arms=("PSM1", "PSM2", "ECM"), include_console=False)


def _tick_us(edit, n: int) -> list[float]:
    sim = Simulation(SCENE, keyframe="surgical", edit_spec=edit)
    sim.run_for(0.2)  # the rings settle on their pegs
    try:
        return time_each(sim.tick, n, warmup=100)
    finally:
        sim.close()


def main(n: int = 2000) -> None:
    task = load_task("peg_transfer_icra")

    def without_noslip(spec):
        task.draw(spec)
        spec.option.noslip_iterations = 0

    figures = {"rings": task.n_rings, "load_average_1min": os.getloadavg()[0]}
    figures.update(summary(_tick_us(None, n), "tick_without_board"))
    figures.update(summary(_tick_us(task.draw, n), "tick_with_board"))
    figures.update(summary(_tick_us(without_noslip, n), "tick_with_board_no_noslip"))

    sim = Simulation(SCENE, keyframe="surgical", edit_spec=task.draw)
    sim.run_for(0.2)
    m, d, cache = sim.model, sim.data, {}
    figures.update(summary(time_each(lambda: task.scene_fields(m, d, cache), n), "scene_fields"))
    monitor = TaskMonitor(task)
    tip = d.site_xpos[m.site("PSM1/tip").id].copy()
    clock = iter(np.arange(10 * n) * 0.001)

    def observe():
        monitor.observe(Sample.of(next(clock), tip, **task.scene_fields(m, d, cache)))

    figures.update(summary(time_each(observe, n), "monitored_sample"))
    sim.close()

    trials = 100
    fields = task.scene_fields(m, d, cache)
    objects = np.broadcast_to(fields["objects"], (trials, task.n_rings, 3))
    grasp = np.broadcast_to(fields["grasp"], (trials, task.n_rings))
    state = task.initial_state(trials)
    times = iter(np.arange(10 * n) * 0.001)

    def batch():
        nonlocal state
        s = Sample.of(np.full(trials, next(times)), np.tile(tip, (trials, 1)), objects=objects,
                      grasp=grasp)  # fmt: skip
        state, _ = task.step(state, s)

    figures.update(summary(time_each(batch, n), f"step_{trials}_trials"))
    write("peg", figures)


if __name__ == "__main__":
    main()
