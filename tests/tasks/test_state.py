"""The task state machine: idle → ready → running → finished → results, reset."""

from __future__ import annotations

import numpy as np
import pytest

from davinci_sim.tasks import Phase, TaskMonitor, initial_state, load_task, reset_state, task_step
from davinci_sim.tasks.base import Sample
from davinci_sim.tasks.state import TaskState


@pytest.fixture(scope="module")
def task():
    return load_task("seed_path")


def test_monitor_through_all_phases(task):
    """Far away: idle; at point 1: ready (waiting there does not start the clock); leaving
    point 1: running; along the path 2 mm off it: still running; at point 5: finished with
    the metrics; then results until reset."""
    mon = TaskMonitor(task)
    assert mon.update(0.0, task.start + [0, 0, 0.03]) == Phase.IDLE
    assert mon.update(0.1, task.start + [0.001, 0, 0]) == Phase.READY
    assert mon.update(0.5, task.start) == Phase.READY
    s = np.linspace(0.0, task.path.length, 2001)
    offset = np.array([0.0, 0.0, 0.002])  # beside every run except the climb 3→4
    times = 1.0 + np.arange(len(s)) * 0.001
    phases = [
        mon.update(tk, p + offset) for tk, p in zip(times, task.path.point_at(s), strict=True)
    ]
    first = phases.index(Phase.RUNNING)
    k = phases.index(Phase.FINISHED)
    assert set(phases[:first]) == {Phase.READY}
    assert set(phases[first:k]) == {Phase.RUNNING}
    assert set(phases[k + 1 :]) <= {Phase.RESULTS}
    r = mon.results
    assert r is not None
    assert r.completion_time[0] == pytest.approx(times[k] - times[first])
    assert 0.0015 < r.deviation_error[0] < 0.002 + 1e-9
    assert r.path_length[0] == pytest.approx(s[k] - s[first], rel=0.02)
    assert mon.update(times[-1] + 0.001, task.finish) == Phase.RESULTS
    assert mon.update(times[-1] + 0.002, task.start) == Phase.RESULTS
    mon.reset()
    assert mon.phase == Phase.IDLE and mon.results is None


def test_finish_needs_progress():
    """A closed loop: being at the finish (= start) right after leaving does not finish."""
    kw = dict(path_length=0.1, start_tolerance=0.003, finish_tolerance=0.003, min_progress=0.5)
    st = initial_state(1)
    st = task_step(st, 0.0, [0.0], [0.0], [0.0], **kw)
    assert st.phase[0] == Phase.READY
    st = task_step(st, 0.1, [0.004], [0.004], [0.004], **kw)
    assert st.phase[0] == Phase.RUNNING and st.t_start[0] == 0.1
    st = task_step(st, 0.2, [0.004], [0.002], [0.004], **kw)  # near the finish too early
    assert st.phase[0] == Phase.RUNNING
    st = task_step(st, 0.3, [0.05], [0.05], [0.06], **kw)
    st = task_step(st, 0.4, [0.002], [0.002], [0.1], **kw)
    assert st.phase[0] == Phase.FINISHED and st.t_finish[0] == 0.4


def test_batch_step_and_partial_reset():
    """Trials advance independently; reset of a subset leaves the others."""
    kw = dict(path_length=0.1, start_tolerance=0.003, finish_tolerance=0.003)
    st = initial_state(3)
    st = task_step(st, 0.0, np.array([0.0, 0.01, 0.0]), np.full(3, 0.1), np.zeros(3), **kw)
    assert st.phase.tolist() == [Phase.READY, Phase.IDLE, Phase.READY]
    st = task_step(st, 0.1, np.array([0.01, 0.0, 0.0]), np.full(3, 0.1), np.zeros(3), **kw)
    assert st.phase.tolist() == [Phase.RUNNING, Phase.READY, Phase.READY]
    st = reset_state(st, np.array([True, False, False]))
    assert st.phase.tolist() == [Phase.IDLE, Phase.READY, Phase.READY]
    assert np.isnan(st.t_start[0])


def test_one_trial_steps_as_a_row_of_a_batch():
    """One trial (the live session) takes the float path of task_step: the same phases,
    times and progress, bit for bit and type for type, as the same trial in a batch."""
    rng = np.random.default_rng(5)
    phases = np.array(list(Phase), dtype=np.int8)
    for _ in range(3000):
        ph = rng.choice(phases)
        t_start, t_finish = rng.choice([np.nan, 1.5]), rng.choice([np.nan, 2.5])
        progress = rng.choice([0.0, 0.01, 0.05, np.nan])
        args = (rng.uniform(0, 3), rng.uniform(0, 0.01), rng.uniform(0, 0.01),
                rng.choice([0.0, 0.02, 0.06, np.nan]))  # fmt: skip
        kw = dict(path_length=0.1, start_tolerance=0.005, finish_tolerance=0.005,
                  min_progress=0.5)  # fmt: skip
        one = TaskState(np.array([ph], np.int8), np.array([t_start]), np.array([t_finish]),
                        np.array([progress]))  # fmt: skip
        two = TaskState(*(np.concatenate([a, a]) for a in one))
        t, ds, df, arc = args
        a = task_step(one, np.array([t]), np.array([ds]), np.array([df]), np.array([arc]), **kw)
        b = task_step(two, np.array([t, t]), np.array([ds, ds]), np.array([df, df]),
                      np.array([arc, arc]), **kw)  # fmt: skip
        for x, y in zip(a, b, strict=True):
            assert x.dtype == y.dtype and x.shape == (1,)
            np.testing.assert_array_equal(x, y[:1], strict=True)


def test_path_task_step_of_one_trial_is_a_batch_row(task):
    """The live session's step (one trial: compiled closest point, distances and the state
    machine on floats) gives the bits of the same trial in a batch, observations included."""
    rng = np.random.default_rng(8)
    state1, state2 = task.initial_state(1), task.initial_state(2)
    s = np.linspace(0, task.path.length, 300)
    points = np.concatenate([task.path.point_at(s), task.path.point_at(s[::-1])])
    for i, p in enumerate(points):
        tip = p + rng.normal(0, 0.002, 3)
        one = Sample.of(0.001 * i, tip.reshape(1, 3))
        two = Sample.of(0.001 * i, np.stack([tip, tip]))
        state1, obs1 = task.step(state1, one)
        state2, obs2 = task.step(state2, two)
        for a, b in zip(state1, state2, strict=True):
            np.testing.assert_array_equal(a, b[:1], strict=True)
        for k in obs1:
            np.testing.assert_array_equal(obs1[k], obs2[k][:1], strict=True)
    assert Phase(int(state1.phase[0])) >= Phase.RUNNING  # the walk went through the phases


def test_inactive_trials_keep_their_state_field_by_field_nested_included():
    """``advance``'s mask keeps an inactive trial's state whatever the fields' shapes: (n,),
    (n, 3) and a nested state (needle driving's passage), also when n is 3 (where a mask of
    shape (n,) would broadcast along a (n, 3) field's last axis instead of its rows)."""
    from typing import NamedTuple

    from davinci_sim.tasks.state import kept_where

    class Inner(NamedTuple):
        inside: np.ndarray
        entry: np.ndarray

    class Outer(NamedTuple):
        phase: np.ndarray
        p: np.ndarray
        inner: Inner

    def state(v: float) -> Outer:
        return Outer(np.full(3, v), np.full((3, 3), v), Inner(np.full(3, v), np.full((3, 2), v)))

    kept = kept_where(np.array([True, False, True]), state(1.0), state(0.0))
    rows = np.array([1.0, 0.0, 1.0])
    np.testing.assert_array_equal(kept.phase, rows)
    np.testing.assert_array_equal(kept.p, np.repeat(rows[:, None], 3, axis=1))
    np.testing.assert_array_equal(kept.inner.inside, rows)
    np.testing.assert_array_equal(kept.inner.entry, np.repeat(rows[:, None], 2, axis=1))
    assert type(kept) is Outer and type(kept.inner) is Inner
