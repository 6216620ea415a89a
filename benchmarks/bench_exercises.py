"""Tick cost of each skill exercise (and of the seed's path task, for comparison).

Per task, at the simulated console of a study set-up (:func:`setup_trial`: PSM, ECM and the
task's MTM, no patient) with a :class:`~davinci_sim.tasks.session.TaskSession` installed:

* ``<task>_step``: the task's state machine and metrics for one sample of one trial
  (:meth:`TaskMonitor.observe` of a recorded live sample), µs;
* ``<task>_session``: the session's whole work in a tick (:meth:`TaskSession.post_step`:
  the live sample — tool pose, camera pose, visibility, contacts, master — then the
  above), µs;
* ``<task>_tick``: one full simulation tick with the session, µs.

``python benchmarks/bench_exercises.py`` writes ``results/exercises.json``.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import davinci_sim  # noqa: E402, F401  (sets MUJOCO_GL)
from common import summary, time_each, write  # noqa: E402
from davinci_sim.study.trial import setup_trial  # noqa: E402
from davinci_sim.tasks import TaskMonitor, install_task, load_task  # noqa: E402
from davinci_sim.tasks.session import live_sample  # noqa: E402

TASKS = ("seed_path", "camera_targeting", "ring_walk", "needle_targeting")


def main(n: int = 2000) -> None:
    figures: dict = {}
    for name in TASKS:
        task = load_task(name)
        setup = setup_trial(task)
        sim = setup.sim
        session = install_task(sim, task)
        sim.run_for(0.05)
        T_task_camera = task.T_task_camera(sim.T_cart_camera())
        sample = live_sample(task, T_task_camera, setup.teleop, setup.console, sim.time)
        monitor = TaskMonitor(task)
        figures.update(
            summary(time_each(lambda m=monitor, s=sample: m.observe(s), n), f"{name}_step")
        )
        figures.update(
            summary(time_each(lambda s=session, w=sim: s.post_step(w.time), n), f"{name}_session")
        )
        figures.update(summary(time_each(sim.tick, n, warmup=20), f"{name}_tick"))
    write("exercises", figures)


if __name__ == "__main__":
    main()
