"""The path kind's compiled tick (tasks/path_row.py) against the Python tick it replaces,
one trial and a batch: the same state, observations, running metrics, previous sample and
results, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from test_metrics_one import _walk

from davinci_sim.kinematics import jit
from davinci_sim.tasks import load_task, path_row
from davinci_sim.tasks.base import _FIELDS, Sample
from davinci_sim.tasks.state import Phase, TaskMonitor

pytestmark = pytest.mark.skipif(not jit.ENABLED, reason="numba is off: nothing is compiled")


def _arrays(x) -> list:
    if x is None:
        return [None]
    if isinstance(x, tuple):
        return [a for part in x for a in _arrays(part)]
    return [x]


def _same(a, b) -> None:
    assert (a is None) == (b is None)
    if a is not None:
        a, b = np.asarray(a), np.asarray(b)
        assert a.dtype == b.dtype and a.shape == b.shape
        np.testing.assert_array_equal(a, b)


_KERNEL = path_row.path_tick_rows


def _observe_both(monkeypatch, compiled, python, sample, active=None) -> bool:
    """``sample`` into both monitors; whether the compiled one ran the compiled tick."""
    calls = []

    def counted(*args):
        calls.append(1)
        return _KERNEL(*args)

    monkeypatch.setattr(path_row, "path_tick_rows", counted)
    compiled.observe(sample, active)
    ran = len(calls)
    monkeypatch.setattr(path_row, "COMPILED", False)
    python.observe(sample, active)
    assert len(calls) == ran <= 1
    monkeypatch.setattr(path_row, "COMPILED", True)
    return bool(ran)


def _check(compiled, python) -> None:
    for x, y in zip(compiled.state, python.state, strict=True):
        _same(x, y)
    assert compiled.observations.keys() == python.observations.keys()
    for k in compiled.observations:
        _same(compiled.observations[k], python.observations[k])
    a, b = compiled.metrics, python.metrics
    for x, y in zip(a._acc, b._acc, strict=True):
        for u, v in zip(_arrays(x), _arrays(y), strict=True):
            _same(u, v)
    _same(a._k, b._k)
    _same(a._prev_in, b._prev_in)
    assert a._missing == b._missing
    for k in _FIELDS:
        _same(getattr(a._prev, k), getattr(b._prev, k))


LACKING = [(0, ()), (1, ()), (2, ("master",)), (3, ("visible", "contacts", "tool_force"))]


@pytest.mark.parametrize("seed, lacking", LACKING)
def test_the_compiled_tick_is_the_python_tick_bit_for_bit(monkeypatch, seed, lacking):
    task = load_task("seed_path")
    compiled, python = TaskMonitor(task), TaskMonitor(task)
    rng = np.random.default_rng(seed)
    phases, python_ticks = set(), 0
    for i, sample in enumerate(_walk(task, rng, 3000)):
        if lacking and i >= 100:
            sample = Sample(*(None if k in lacking else getattr(sample, k) for k in _FIELDS))
        python_ticks += not _observe_both(monkeypatch, compiled, python, sample)
        _check(compiled, python)
        phases.add(compiled.phase)
    # (only the sample that drops the contacts the previous one had takes the reducers)
    assert python_ticks == ("contacts" in lacking)
    assert {Phase.READY, Phase.RUNNING, Phase.FINISHED} <= phases
    assert compiled.results is not None
    for name in compiled.results._fields:
        _same(compiled.results[name], python.results[name])
    row = compiled.results.row()
    assert row["path_length"] > 0 and row["samples"] > 1000
    assert lacking or (row["clutch_count"] > 0 and row["instrument_collisions"] > 0)


def test_the_state_machines_edges_as_the_python_tick(monkeypatch):
    """At point 1 (READY), leaving it (RUNNING), at the last point (FINISHED), then RESULTS;
    after a reset, a NaN tip while running: the progress NaN, so no finish, as numpy's
    maximum makes it."""
    task = load_task("seed_path")
    compiled, python = TaskMonitor(task), TaskMonitor(task)
    start, finish = np.asarray(task.start), np.asarray(task.finish)
    mid = np.asarray(task.waypoints, dtype=float)[len(task.waypoints) // 2]
    away = start + 3 * task.start_tolerance
    rounds = (
        ([start, start, away, mid, finish, finish, mid], Phase.RESULTS),
        ([start, start, away, np.full(3, np.nan), mid, finish, finish], Phase.RUNNING),
    )
    for tips, end in rounds:
        for k, tip in enumerate(tips):
            assert _observe_both(monkeypatch, compiled, python, Sample.of(0.01 * k, tip))
            _check(compiled, python)
        assert compiled.phase == python.phase == end
        compiled.reset()
        python.reset()


def test_an_environments_active_trial_takes_the_compiled_tick(monkeypatch):
    """The single environment passes its one trial's activity: compiled, as the Python
    tick with the mask (an inactive trial's state held, its sample not measured)."""
    task = load_task("seed_path")
    compiled, python = TaskMonitor(task), TaskMonitor(task)
    on, off = np.ones(1, dtype=bool), np.zeros(1, dtype=bool)
    for i, sample in enumerate(_walk(task, np.random.default_rng(7), 1500)):
        active = off if 200 <= i < 210 else on
        assert _observe_both(monkeypatch, compiled, python, sample, active)
        _check(compiled, python)
    assert compiled.results is not None


def _batch(task, rng, n: int, ticks: int):
    """Samples of ``n`` trials walking the path at their own paces (each trial's walk, the
    shorter ones holding their last sample), the optional fields toggling."""
    seeds = rng.integers(1 << 30, size=n)
    walks = [list(_walk(task, np.random.default_rng(seeds[i]), int(ticks * (1 - 0.15 * i))))
             for i in range(n)]  # fmt: skip
    for k in range(ticks):
        rows = [w[min(k, len(w) - 1)] for w in walks]
        yield Sample(*(None if getattr(rows[0], f) is None else np.concatenate(
            [getattr(r, f) for r in rows]) for f in _FIELDS))  # fmt: skip


def test_a_batch_with_trials_ending_at_their_own_time_as_the_python_tick(monkeypatch):
    """The study's batch: three trials, each inactive once it has finished (as the batch
    marks them), then all but one reset (a new repetition)."""
    task = load_task("seed_path")
    compiled, python = TaskMonitor(task, 3), TaskMonitor(task, 3)
    active = np.ones(3, dtype=bool)
    for sample in _batch(task, np.random.default_rng(11), 3, 3000):
        assert _observe_both(monkeypatch, compiled, python, sample, active.copy())
        _check(compiled, python)
        active &= compiled.state.phase < Phase.FINISHED
    assert not active.any() and compiled.results is not None
    for name in compiled.results._fields:
        _same(compiled.results[name], python.results[name])
    for monitor in (compiled, python):
        monitor.state = task.reset_state(monitor.state, np.array([True, True, False]))
        monitor.metrics.reset(np.array([True, True, False]))
    for sample in _batch(task, np.random.default_rng(12), 3, 600):
        assert _observe_both(monkeypatch, compiled, python, sample)
        _check(compiled, python)


def test_other_kinds_take_the_python_tick():
    ring = load_task("ring_walk")
    monitor = TaskMonitor(ring)
    sample = Sample.of(0.0, np.zeros(3))
    assert path_row.advance_rows(ring, monitor.state, monitor.metrics, sample) is None
