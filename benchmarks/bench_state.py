"""Saving and restoring the simulation (:mod:`davinci_sim.sim.state`): ``get_state``,
``set_state`` and ``reset`` of the full system with the console following, and a study
trial's start restored from the per-process cache instead of built (model + ~1,200 ticks).

``python benchmarks/bench_state.py`` writes ``results/state.json``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import davinci_sim  # noqa: E402, F401  (sets MUJOCO_GL)
from common import summary, time_each, write  # noqa: E402
from davinci_sim.study.trial import build_setup, setup_trial  # noqa: E402
from davinci_sim.system import ConsoleDescription, SystemDescription, build_simulation  # noqa: E402
from davinci_sim.tasks import load_task  # noqa: E402


def main(n: int = 200) -> None:
    console = ConsoleDescription(operator_present=True, teleop_enabled=True)
    sim = build_simulation(SystemDescription("full", console=console))
    sim.run_for(0.5)
    state = sim.get_state()
    figures = {"full_system_components": len(sim.components)}
    figures.update(summary(time_each(sim.get_state, n, warmup=10), "get_state"))
    figures.update(summary(time_each(lambda: sim.set_state(state), n, warmup=10), "set_state"))
    figures.update(summary(time_each(sim.reset, n, warmup=10), "reset"))
    task = load_task("seed_path")
    t0 = time.perf_counter()
    build_setup(task)
    figures["trial_setup_built_s"] = time.perf_counter() - t0
    setup_trial(task)  # cached from here on
    figures.update(
        summary(time_each(lambda: setup_trial(task), n, warmup=10), "trial_setup_restored")
    )
    write("state", figures)


if __name__ == "__main__":
    main()
