"""Trainees on an ideal teleoperation, without the simulator: for tests and quick checks.

The tool follows the hand exactly, ``tool = tool_start + scale·(hand − hand_start)`` (no
arm dynamics, no servo lag), the fixture's force (camera frame = HRSV axes) acts on the hand
from the tool's position and filtered velocity, and each tick's
:class:`~davinci_sim.tasks.Sample` of the tool goes through a
:class:`~davinci_sim.tasks.TaskMonitor` of the path (the task's state machine and metrics,
as in the simulator). This is *not* the study: the study drives the simulated MTM and PSM through
the console's teleoperation. It is what the trainee model does on its own, fast.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from davinci_sim.haptics.fixture import Fixture
from davinci_sim.haptics.velocity import VelocityFilter
from davinci_sim.operators.trainee import SyntheticTrainee
from davinci_sim.tasks.base import Sample
from davinci_sim.tasks.metrics import MetricValues
from davinci_sim.tasks.state import Phase, TaskMonitor
from davinci_sim.tasks.task import PathTask


class IdealRun(NamedTuple):
    """Outcome of :func:`run_ideal`."""

    metrics: MetricValues
    """Per trial (n,), the path task's metrics; nan/0 for trials that did not finish."""
    finished: np.ndarray
    """(n,) bool."""
    time: np.ndarray
    """(K,) s, if recorded."""
    tool: np.ndarray | None
    """(n, K, 3) tool tips, camera frame, m, if recorded."""
    force: np.ndarray | None
    """(n, K, 3) forces on the hand, N, if recorded."""
    hand: np.ndarray | None
    """(n, K, 3) hand positions, HRSV, m, if recorded."""


def run_ideal(
    trainee: SyntheticTrainee,
    *,
    tool_start,
    fixture: Fixture | None,
    start_tolerance: float,
    finish_tolerance: float,
    tube_radius: float,
    min_progress: float = 0.5,
    duration: float = 60.0,
    record: bool = False,
) -> IdealRun:
    """Run ``trainee`` (its path in the camera frame) on an ideal teleop until every trial
    has finished or ``duration`` s have passed.

    Args:
        trainee: a fresh trainee.
        tool_start: tool tips at the start, (n, 3), camera frame, m.
        fixture: force law in the camera frame (None: no force).
        start_tolerance, finish_tolerance, tube_radius, min_progress: the task's.
        duration: longest run, s.
        record: keep the trajectories (memory n·K·9 floats).
    """
    n, dt = trainee.n, trainee.dt
    task = PathTask.along(
        trainee.path,
        start_tolerance=start_tolerance,
        finish_tolerance=finish_tolerance,
        tube_radius=tube_radius,
        min_progress=min_progress,
    )
    monitor = TaskMonitor(task, n)
    tool0 = np.asarray(tool_start, dtype=float).copy()
    hand0 = trainee.x.copy()
    tool = tool0.copy()
    velocity = VelocityFilter((n,), dt=dt)
    force = np.zeros((n, 3))
    rec_t, rec_tool, rec_force, rec_hand = [], [], [], []
    for k in range(int(round(duration / dt))):
        t = k * dt
        v_tool = velocity.update(tool)
        force = np.zeros((n, 3)) if fixture is None else fixture.force(tool, v_tool)
        phase = monitor.observe(Sample.of(t, tool, force))
        if record:
            rec_t.append(t)
            rec_tool.append(tool.copy())
            rec_force.append(force.copy())
            rec_hand.append(trainee.x.copy())
        if np.all(phase >= Phase.FINISHED):
            break
        hand = trainee.step(dt, tool, force).position
        tool = tool0 + trainee.scale * (hand - hand0)
    finished = monitor.state.phase >= Phase.FINISHED
    stack = (lambda a: np.stack(a, axis=1)) if record else (lambda a: None)
    return IdealRun(
        monitor.metrics.result(),
        finished,
        np.array(rec_t),
        stack(rec_tool),
        stack(rec_force),
        stack(rec_hand),
    )
