"""Training tasks: path-following task files, their states, metrics and scene drawing.

* :class:`PathTask`, :func:`load_task`, :func:`available_tasks` — tasks as YAML/JSON files
  (task.py); ``load_task("seed_path")`` is the seed paper's task.
* :func:`task_step`, :class:`TaskMonitor`, :class:`Phase` — idle → ready → running →
  finished → results (state.py).
* :func:`repetition_metrics`, :class:`MetricsAccumulator` — deviation error (eq. 8), time,
  path length, speed, forces, time outside the tube, clutches (metrics.py).
* :func:`add_path_visual` — the path and numbered markers in a ``mujoco.MjSpec`` (scene.py).
* :class:`TaskSession`, :func:`install_task` — a task done at the simulated console, its
  fixture in the haptic loop and its repetitions measured (session.py).
"""

from davinci_sim.tasks.metrics import MetricsAccumulator, RepetitionMetrics, repetition_metrics
from davinci_sim.tasks.scene import add_path_visual
from davinci_sim.tasks.session import TaskSession, TaskSessionState, install_task
from davinci_sim.tasks.state import (
    Phase,
    TaskMonitor,
    TaskState,
    initial_state,
    reset_state,
    task_step,
)
from davinci_sim.tasks.task import PathTask, TaskError, available_tasks, load_task, save_task

__all__ = [
    "MetricsAccumulator",
    "PathTask",
    "Phase",
    "RepetitionMetrics",
    "TaskError",
    "TaskMonitor",
    "TaskSession",
    "TaskSessionState",
    "TaskState",
    "add_path_visual",
    "available_tasks",
    "initial_state",
    "install_task",
    "load_task",
    "repetition_metrics",
    "reset_state",
    "save_task",
    "task_step",
]
