"""The states of a path-following repetition, as a pure step function over a batch of trials.

::

    IDLE ──tip within start_tolerance of point 1──> READY
    READY ──tip leaves that sphere──> RUNNING          (the clock starts: t_start)
    RUNNING ──tip within finish_tolerance of the last point,
              having been past min_progress of the path──> FINISHED   (t_finish)
    FINISHED ──next step──> RESULTS                    (the metrics are final)
    any ──reset──> IDLE

RUNNING starts when the tip *leaves* the start sphere, so time spent waiting at point 1 does
not count. Progress is the largest arc length of the tip's closest path point seen while
running; requiring some (default half the path) before finishing makes paths whose ends are
close together (or loops) work. :func:`task_step` advances any number of trials at once;
:class:`TaskMonitor` wraps it for a single trial with recording and the metrics.
"""

from __future__ import annotations

import copy
import math
from enum import IntEnum
from typing import NamedTuple

import numpy as np

from davinci_sim.geometry.path import ClosestPoint
from davinci_sim.tasks.metrics import MetricsAccumulator, RepetitionMetrics
from davinci_sim.tasks.task import PathTask


class Phase(IntEnum):
    IDLE = 0
    READY = 1
    RUNNING = 2
    FINISHED = 3
    RESULTS = 4


class TaskState(NamedTuple):
    """State of a batch of trials, each array of shape (n,)."""

    phase: np.ndarray
    """:class:`Phase` values, int."""
    t_start: np.ndarray
    """Time RUNNING began, s (nan before)."""
    t_finish: np.ndarray
    """Time FINISHED was reached, s (nan before)."""
    progress: np.ndarray
    """Largest arc length reached while running, m."""


def initial_state(n: int) -> TaskState:
    """``n`` trials in IDLE."""
    return TaskState(
        np.full(n, Phase.IDLE, dtype=np.int8),
        np.full(n, np.nan),
        np.full(n, np.nan),
        np.zeros(n),
    )


def reset_state(state: TaskState, mask=None) -> TaskState:
    """Back to IDLE, all trials or those where ``mask`` (n,) is true."""
    fresh = initial_state(len(state.phase))
    if mask is None:
        return fresh
    m = np.asarray(mask, dtype=bool)
    return TaskState(*(np.where(m, f, s) for f, s in zip(fresh, state, strict=True)))


def task_step(
    state: TaskState,
    time: float | np.ndarray,
    dist_start,
    dist_finish,
    arc_length,
    *,
    path_length: float,
    start_tolerance: float,
    finish_tolerance: float,
    min_progress: float = 0.5,
) -> TaskState:
    """Advance the state machine of each trial by one sample (pure).

    Args:
        state: the trials' state (n,).
        time: this sample's time, s (scalar or (n,)).
        dist_start: distance of each tip to point 1, (n,), m.
        dist_finish: distance of each tip to the last point, (n,), m.
        arc_length: arc length of each tip's closest path point, (n,), m.
        path_length, start_tolerance, finish_tolerance, min_progress: the task's.
    """
    phase = state.phase
    t = np.broadcast_to(np.asarray(time, dtype=float), phase.shape)
    at_start = np.asarray(dist_start) <= start_tolerance
    at_finish = np.asarray(dist_finish) <= finish_tolerance
    running = phase == Phase.RUNNING
    progress = np.where(running, np.maximum(state.progress, arc_length), state.progress)
    new = phase.copy()
    new[(phase == Phase.IDLE) & at_start] = Phase.READY
    begin = (phase == Phase.READY) & ~at_start
    new[begin] = Phase.RUNNING
    done = running & at_finish & (progress >= min_progress * path_length)
    new[done] = Phase.FINISHED
    new[phase == Phase.FINISHED] = Phase.RESULTS
    return TaskState(
        new,
        np.where(begin, t, state.t_start),
        np.where(done, t, state.t_finish),
        np.where(begin, arc_length, progress),
    )


def task_sample(state: TaskState, task: PathTask, time, tip) -> tuple[TaskState, ClosestPoint]:
    """:func:`task_step` of ``task`` for tool tips ``tip`` (n, 3), m, in the task's frame;
    returns the new state and the tips' closest points on the path (for the metrics)."""
    path = task.path
    cp = path.closest_point(tip)
    new = task_step(
        state,
        time,
        np.linalg.norm(tip - task.start, axis=1),
        np.linalg.norm(tip - task.finish, axis=1),
        cp.arc_length,
        path_length=path.length,
        start_tolerance=task.start_tolerance,
        finish_tolerance=task.finish_tolerance,
        min_progress=task.min_progress,
    )
    return new, cp


class TaskMonitor:
    """One trial of ``task``: feed it each sample (time, tip, force, clutch); it runs the
    state machine, accumulates the metrics while RUNNING, and has them once FINISHED.

    Positions in the task's frame (convert camera-frame tips with the camera pose first).
    """

    def __init__(self, task: PathTask) -> None:
        self.task = task
        self.reset()

    def reset(self) -> None:
        self.state = initial_state(1)
        self._metrics = MetricsAccumulator(1, tube_radius=self.task.tube_radius)
        self.results: RepetitionMetrics | None = None
        self.distance = math.nan
        """Distance of the last sample's tip to the path, m (nan before the first)."""

    @property
    def phase(self) -> Phase:
        return Phase(int(self.state.phase[0]))

    def update(self, time: float, tip, force=(0.0, 0.0, 0.0), clutch: bool = False) -> Phase:
        """One sample: tip position (3,), m; force on the hand (3,), N; clutch pressed."""
        task = self.task
        p = np.asarray(tip, dtype=float).reshape(1, 3)
        self.state, cp = task_sample(self.state, task, time, p)
        self.distance = float(cp.distance[0])
        phase = self.phase
        # The sample where RUNNING begins is the first of the repetition, the one where
        # FINISHED is reached its last.
        if phase in (Phase.RUNNING, Phase.FINISHED):
            self._metrics.update(
                np.array([True]),
                time,
                p,
                cp.distance,
                np.asarray(force, dtype=float).reshape(1, 3),
                np.array([bool(clutch)]),
            )
        if phase == Phase.FINISHED:
            self.results = self._metrics.result()
        return phase

    def get_state(self) -> dict:
        """The state machine, the metrics accumulated so far, the results and distance."""
        return {
            "state": TaskState(*(np.copy(a) for a in self.state)),
            "metrics": self._metrics.get_state(),
            "results": None if self.results is None else copy.deepcopy(self.results),
            "distance": self.distance,
        }

    def set_state(self, state: dict) -> None:
        self.state = TaskState(*(np.copy(a) for a in state["state"]))
        self._metrics.set_state(state["metrics"])
        self.results = None if state["results"] is None else copy.deepcopy(state["results"])
        self.distance = state["distance"]
