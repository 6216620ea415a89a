"""The tick cost of the exercises with free objects: peg transfer
(:mod:`davinci_sim.tasks.peg`), needle pick-up (:mod:`davinci_sim.tasks.needle_pickup`) and
needle driving (:mod:`davinci_sim.tasks.needle_drive`: the needle and the suture pad's skin).
For each, the physics step of a scene with the task's objects (the board and three rings;
the foam park and the needle; the park, the needle and the pad; PSM1, PSM2 and the ECM)
against the same scene without them and with them but without the noslip solver, the task's
reading of the scene (``scene_fields``: object centres and jaw contacts), one monitored
sample (state machine and metrics) for one trial, and the pure step for 100 trials at once.

The objects rest where they start (contacts every step) while the arms hold their homed
pose. ``python benchmarks/bench_peg.py`` writes ``results/peg.json``,
``results/needle.json`` and ``results/needle_drive.json``.
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


def measure(task, objects: str, n: int) -> dict:
    """The figures of ``task`` (see the module docstring); ``objects`` names them in the
    keys (``board``, ``needle``)."""

    def without_noslip(spec):
        task.draw(spec)
        spec.option.noslip_iterations = 0

    k = getattr(task, "n_rings", 1)
    figures = {"objects": k, "load_average_1min": os.getloadavg()[0]}
    figures.update(summary(_tick_us(None, n), f"tick_without_{objects}"))
    figures.update(summary(_tick_us(task.draw, n), f"tick_with_{objects}"))
    figures.update(summary(_tick_us(without_noslip, n), f"tick_with_{objects}_no_noslip"))

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
    fields = {key: np.broadcast_to(v, (trials, *np.shape(v)))
              for key, v in task.scene_fields(m, d, cache).items()}  # fmt: skip
    state = task.initial_state(trials)
    times = iter(np.arange(10 * n) * 0.001)

    def batch():
        nonlocal state
        s = Sample.of(np.full(trials, next(times)), np.tile(tip, (trials, 1)), **fields)
        state, _ = task.step(state, s)

    figures.update(summary(time_each(batch, n), f"step_{trials}_trials"))
    return figures


def main(n: int = 2000) -> None:
    write("peg", measure(load_task("peg_transfer_icra"), "board", n))
    write("needle", measure(load_task("needle_pickup"), "needle", n))
    write("needle_drive", measure(load_task("needle_drive"), "pad_and_needle", n))


if __name__ == "__main__":
    main()
