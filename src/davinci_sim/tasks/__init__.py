"""Training tasks: the Task protocol and its kinds, their states, metrics and scene drawing.

* :class:`Task`, :class:`Sample`, :func:`load_task`, :func:`task_kinds` — what every kind of
  task provides, the one sample record of a tick, task files (``kind:`` selects the class)
  and the registry of kinds (base.py).
* :class:`PathTask` — the path-following kind (``path``, the default); ``load_task("seed_path")``
  is the seed paper's task (task.py).
* :func:`task_step`, :class:`TaskMonitor`, :func:`advance`, :class:`Phase` — idle → ready →
  running → finished → results, and the glue from samples to metrics for every kind
  (state.py).
* :class:`Metric`, :class:`MetricsAccumulator`, :data:`PATH_METRICS`,
  :func:`repetition_metrics` — metrics declared once per kind and computed from the samples
  (metrics.py).
* :data:`TRAINER_METRICS`, :func:`trainer_metrics`, :class:`InstrumentContacts` — the metrics
  trainers score (collisions, excessive force, out of view, master workspace, drops, missed
  targets) declared once for every kind (trainer.py).
* :class:`Scoring`, :data:`SCORE_COLUMNS`, :func:`load_reference` — an attempt's overall
  score (0-100 %) and pass/fail against marks from an expert reference (scoring.py).
* :func:`add_path_visual` — the path and numbered markers in a ``mujoco.MjSpec`` (scene.py).
* :class:`TaskSession`, :func:`install_task` — a task done at the simulated console, its
  fixture in the haptic loop and its repetitions measured (session.py).
"""

from davinci_sim.tasks.base import (
    Sample,
    Task,
    TaskError,
    TeleopSpec,
    available_tasks,
    load_task,
    save_task,
    task_from_dict,
    task_kinds,
    task_to_dict,
)
from davinci_sim.tasks.metrics import (
    PATH_METRICS,
    Metric,
    MetricsAccumulator,
    MetricValues,
    RepetitionMetrics,
    repetition_metrics,
)
from davinci_sim.tasks.scene import add_path_visual
from davinci_sim.tasks.scoring import SCORE_COLUMNS, Scoring, load_reference
from davinci_sim.tasks.session import TaskSession, TaskSessionState, install_task
from davinci_sim.tasks.state import (
    Phase,
    TaskMonitor,
    TaskState,
    advance,
    initial_state,
    reset_state,
    task_step,
)
from davinci_sim.tasks.task import PathTask
from davinci_sim.tasks.trainer import TRAINER_METRICS, InstrumentContacts, trainer_metrics

__all__ = [
    "PATH_METRICS",
    "SCORE_COLUMNS",
    "TRAINER_METRICS",
    "InstrumentContacts",
    "Scoring",
    "load_reference",
    "trainer_metrics",
    "Metric",
    "MetricValues",
    "MetricsAccumulator",
    "PathTask",
    "Phase",
    "RepetitionMetrics",
    "Sample",
    "Task",
    "TaskError",
    "TaskMonitor",
    "TaskSession",
    "TaskSessionState",
    "TaskState",
    "TeleopSpec",
    "add_path_visual",
    "advance",
    "available_tasks",
    "initial_state",
    "install_task",
    "load_task",
    "repetition_metrics",
    "reset_state",
    "save_task",
    "task_from_dict",
    "task_kinds",
    "task_step",
    "task_to_dict",
]

# The path kind's compiled tick, compiled (or loaded from numba's cache) with the package:
# ``advance`` looks it up at its first tick, which must not wait for a compile in the loop.
from davinci_sim.tasks import path_row as _path_row  # noqa: E402, F401
