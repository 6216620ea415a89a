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
close together (or loops) work. :func:`task_step` advances any number of trials at once
(the path kind's :meth:`~davinci_sim.tasks.task.PathTask.step`).

:func:`advance` and :class:`TaskMonitor` are the glue from samples to metrics for every kind
of task (:class:`~davinci_sim.tasks.base.Task`): each tick one
:class:`~davinci_sim.tasks.base.Sample` of n trials goes through the task's state machine
and, for the trials RUNNING or just FINISHED, into the metrics
(:class:`~davinci_sim.tasks.metrics.MetricsAccumulator`). The live session, the study's live
and batched trials and the offline runs all use them.
"""

from __future__ import annotations

import copy
import math
from enum import IntEnum
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from davinci_sim.kinematics import jit
from davinci_sim.tasks.base import Sample

if TYPE_CHECKING:
    from davinci_sim.tasks.base import Task
    from davinci_sim.tasks.metrics import MetricsAccumulator, MetricValues


class Phase(IntEnum):
    IDLE = 0
    READY = 1
    RUNNING = 2
    FINISHED = 3
    RESULTS = 4


#: The phases as plain ints for array comparisons (an IntEnum against an array costs five
#: times an int, at every tick of the live session and the study's batches).
_IDLE, _READY, _RUNNING, _FINISHED, _RESULTS = (int(p) for p in Phase)


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
    if phase.shape == (1,):  # one trial (the live session, every tick): on floats
        return _task_step_one(
            state, time, dist_start, dist_finish, arc_length,
            path_length * min_progress, start_tolerance, finish_tolerance,
        )  # fmt: skip
    t = np.broadcast_to(np.asarray(time, dtype=float), phase.shape)
    at_start = np.asarray(dist_start) <= start_tolerance
    at_finish = np.asarray(dist_finish) <= finish_tolerance
    running = phase == _RUNNING
    progress = np.where(running, np.maximum(state.progress, arc_length), state.progress)
    new = phase.copy()
    new[(phase == _IDLE) & at_start] = _READY
    begin = (phase == _READY) & ~at_start
    new[begin] = _RUNNING
    done = running & at_finish & (progress >= min_progress * path_length)
    new[done] = _FINISHED
    new[phase == _FINISHED] = _RESULTS
    return TaskState(
        new,
        np.where(begin, t, state.t_start),
        np.where(done, t, state.t_finish),
        np.where(begin, arc_length, progress),
    )


def _task_step_one(state, time, dist_start, dist_finish, arc_length, min_arc, start_tol,
                   finish_tol) -> TaskState:  # fmt: skip
    """:func:`task_step` of one trial on Python floats: the same comparisons and the same
    results (arrays of the same types, ``np.maximum``'s NaN rule), without the array
    arithmetic (``min_arc``: ``min_progress · path_length``, as the batch form computes it)."""
    t = float(np.asarray(time, dtype=float).reshape(-1)[0])
    at_start = bool(np.asarray(dist_start).reshape(-1)[0] <= start_tol)
    at_finish = bool(np.asarray(dist_finish).reshape(-1)[0] <= finish_tol)
    arc = float(np.asarray(arc_length, dtype=float).reshape(-1)[0])
    new, begin, done, progress = phase_step(
        int(state.phase[0]), float(state.progress[0]), at_start, at_finish, arc, min_arc
    )
    return TaskState(
        np.array([new], dtype=state.phase.dtype),
        np.array([t]) if begin else state.t_start.astype(float),
        np.array([t]) if done else state.t_finish.astype(float),
        np.array([arc if begin else progress], dtype=float),
    )


@jit.helper
def phase_step(phase, progress, at_start, at_finish, arc, min_arc):
    """One trial's state machine on floats (:func:`task_step`'s rules): from ``phase`` (an
    int of :class:`Phase`) with the ``progress`` so far (m), this sample's tip at point 1
    (``at_start``) or at the last point (``at_finish``) and its closest point's arc length
    ``arc`` (m), ``min_arc`` the progress a finish needs (m). Returns ``(new phase,
    begins, finishes, progress)``: the progress is ``np.maximum(progress, arc)`` while
    RUNNING (NaN if either is), else unchanged. Compiled into the path kind's tick
    (:mod:`~davinci_sim.tasks.path_row`)."""
    running = phase == _RUNNING
    if running:  # np.maximum: NaN if either is
        if progress != progress:
            pass
        elif arc != arc or progress < arc:
            progress = arc
    begin = phase == _READY and not at_start
    done = running and at_finish and progress >= min_arc
    new = phase
    if phase == _IDLE and at_start:
        new = _READY
    elif begin:
        new = _RUNNING
    elif done:
        new = _FINISHED
    elif phase == _FINISHED:
        new = _RESULTS
    return new, begin, done, progress


def measuring(phase) -> np.ndarray:
    """(n,) bool: the trials whose current sample belongs to the repetition (RUNNING, or
    FINISHED at this sample)."""
    return (phase == _RUNNING) | (phase == _FINISHED)


def kept_where(active: np.ndarray, new, old):
    """``new`` state where ``active`` (n,) bool, else ``old``: field by field, a field of
    any shape (n, ...), a nested state (needle driving's passage) field by field in turn."""
    if isinstance(new, tuple):
        return type(new)(*(kept_where(active, a, b) for a, b in zip(new, old, strict=True)))
    a = np.asarray(new)
    return np.where(np.reshape(active, (-1,) + (1,) * (a.ndim - 1)), a, old)


def advance(task: Task, state, metrics: MetricsAccumulator, sample: Sample, active=None):
    """One sample of n trials through ``task``'s state machine and into ``metrics``.

    Args:
        task: the task (any kind).
        state: the trials' state (``task.initial_state(n)``).
        metrics: the trials' accumulator (``task.metrics_accumulator(n)``), updated.
        sample: this tick's sample of every trial.
        active: (n,) bool, the trials still going (None: all); the others keep their
            state and are not measured.

    Returns:
        ``(new state, observations)`` (:meth:`~davinci_sim.tasks.base.Task.step`).
    """
    from davinci_sim.tasks.path_row import advance_rows  # (the path kind's compiled tick)

    stepped = advance_rows(task, state, metrics, sample, active)
    if stepped is not None:
        return stepped
    new, obs = task.step(state, sample)
    if active is not None:
        new = kept_where(active, new, state)
    measure = measuring(new.phase)
    if active is not None:
        measure = measure & active
    metrics.update(measure, sample, obs)
    return new, obs


class TaskMonitor:
    """n trials of ``task`` (any kind): feed it each tick's
    :class:`~davinci_sim.tasks.base.Sample` (:meth:`observe`) or, for one trial, the
    sample's values (:meth:`update`); it runs the state machine, accumulates the metrics
    while RUNNING, and has them (:attr:`results`) once every trial is FINISHED.

    Positions in the task's frame (convert camera-frame tips with the camera pose first).
    """

    def __init__(self, task: Task, n: int = 1) -> None:
        self.task = task
        self.n = n
        self.reset()

    def reset(self) -> None:
        self.state = self.task.initial_state(self.n)
        self.metrics = self.task.metrics_accumulator(self.n)
        self.results: MetricValues | None = None
        self.observations: dict[str, np.ndarray] = {}
        """The task's observations of the last sample (empty before the first)."""

    @property
    def phase(self) -> Phase:
        """Phase of the first trial."""
        return Phase(int(self.state.phase[0]))

    @property
    def distance(self) -> float:
        """Distance of the first trial's last tip to the task's geometry (the path), m (nan
        before the first sample)."""
        d = self.observations.get("distance")
        return math.nan if d is None else float(d[0])

    def observe(self, sample: Sample, active=None) -> np.ndarray:
        """One sample of the n trials (:func:`advance`); returns their phases (n,)."""
        self.state, self.observations = advance(self.task, self.state, self.metrics, sample, active)
        if self.results is None and np.all(self.state.phase >= _FINISHED):
            self.results = self.metrics.result()
        return self.state.phase

    def update(self, time: float, tip, force=(0.0, 0.0, 0.0), clutch: bool = False) -> Phase:
        """One sample of a single trial: tip position (3,), m; force on the hand (3,), N;
        clutch pressed."""
        self.observe(Sample.of(time, tip, force, clutch))
        return self.phase

    def get_state(self) -> dict:
        """The state machine, the metrics accumulated so far, the results and the last
        observations (copies)."""
        return {
            "state": copy.deepcopy(self.state),
            "metrics": self.metrics.get_state(),
            "results": copy.deepcopy(self.results),
            "observations": {k: np.copy(v) for k, v in self.observations.items()},
        }

    def set_state(self, state: dict) -> None:
        self.state = copy.deepcopy(state["state"])
        self.metrics.set_state(state["metrics"])
        self.results = copy.deepcopy(state["results"])
        self.observations = {k: np.copy(v) for k, v in state["observations"].items()}
