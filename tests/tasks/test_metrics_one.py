"""The path kind's metrics of one trial on floats (tasks/metrics_one.py) against the
reducers they replace at 1 kHz: the same accumulators and results, bit for bit."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from davinci_sim.tasks import load_task
from davinci_sim.tasks.base import Sample
from davinci_sim.tasks.state import Phase, TaskMonitor


def _walk(task, rng, ticks: int):
    """Samples of a tip that starts at point 1 and walks the path with noise (off the tube
    now and then), with the clutch, contacts, visibility and contact force toggling."""
    waypoints = np.asarray(task.waypoints, dtype=float)
    per_segment = ticks // (len(waypoints) - 1)
    legs = zip(waypoints[:-1], waypoints[1:], strict=True)
    along = np.concatenate([np.linspace(a, b, per_segment, endpoint=False) for a, b in legs])
    along = np.concatenate([np.repeat(waypoints[:1], 30, axis=0), along, waypoints[-1:]])
    for i, p in enumerate(along):
        tip = p + (rng.normal(scale=0.002, size=3) if i > 30 else 0.0)
        yield Sample.of(
            0.001 * i, tip, rng.normal(scale=0.5, size=3), bool(rng.random() < 0.05),
            visible=bool(rng.random() < 0.9), master=rng.normal(scale=0.05, size=3),
            contacts=int(rng.integers(0, 2) if rng.random() < 0.1 else 0),
            tool_force=float(rng.exponential(1.0)),
        )  # fmt: skip


def _state(monitor) -> list:
    m = monitor.metrics
    return [copy.deepcopy(m._acc), m._k.copy(), m._prev_in.copy()]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_float_path_is_the_reducers_bit_for_bit(seed):
    task = load_task("seed_path")
    floats, arrays = TaskMonitor(task), TaskMonitor(task)
    assert floats.metrics.floats
    arrays.metrics.floats = False  # (the reducers' path, the oracle)
    rng = np.random.default_rng(seed)
    phases = set()
    for sample in _walk(task, rng, 3000):
        floats.observe(sample)
        arrays.observe(sample)
        phases.add(floats.phase)
        a, b = _state(floats), _state(arrays)
        for x, y in zip(a[0], b[0], strict=True):
            if x is None:
                assert y is None
            else:
                for u, v in zip(x if isinstance(x, tuple) else (x,),
                                y if isinstance(y, tuple) else (y,), strict=True):  # fmt: skip
                    assert u.dtype == v.dtype
                    np.testing.assert_array_equal(u, v)
        np.testing.assert_array_equal(a[1], b[1])
        np.testing.assert_array_equal(a[2], b[2])
    assert {Phase.READY, Phase.RUNNING} <= phases and floats.results is not None
    for name in floats.results._fields:
        got, want = floats.results[name], arrays.results[name]
        assert got.dtype == want.dtype
        np.testing.assert_array_equal(got, want)
    # Every metric measured something (none stayed at its initial value by a wrong index).
    row = floats.results.row()
    assert row["path_length"] > 0 and row["clutch_count"] > 0 and row["out_of_view"] > 0
    assert row["instrument_collisions"] > 0 and row["excessive_force"] > 0
    assert row["master_workspace"] > 0 and math.isfinite(row["completion_time"])


@pytest.mark.parametrize("lacking", [("master",), ("visible", "contacts", "tool_force")])
def test_a_sample_without_a_field_marks_its_metric_unavailable_as_the_reducers(lacking):
    """(The learning environments' samples have no master, visibility or contacts.)"""
    task = load_task("seed_path")
    floats, arrays = TaskMonitor(task), TaskMonitor(task)
    arrays.metrics.floats = False
    rng = np.random.default_rng(5)
    for i, sample in enumerate(_walk(task, rng, 800)):
        if i >= 100:
            sample = Sample(*(None if k in lacking else getattr(sample, k)
                              for k in sample.__dataclass_fields__))  # fmt: skip
        floats.observe(sample)
        arrays.observe(sample)
        for x, y in zip(floats.metrics._acc, arrays.metrics._acc, strict=True):
            for u, v in zip(x if isinstance(x, tuple) else (x,),
                            y if isinstance(y, tuple) else (y,), strict=True):  # fmt: skip
                np.testing.assert_array_equal(u, v)
    assert floats.metrics._missing == arrays.metrics._missing
    assert len(floats.metrics._missing) == len(lacking)
    assert floats.results is not None
    for name in floats.results._fields:
        np.testing.assert_array_equal(floats.results[name], arrays.results[name])


def test_other_declarations_and_batches_keep_the_reducers():
    task = load_task("seed_path")
    assert not task.metrics_accumulator(1).floats or task.metrics_accumulator(4).n == 4
    assert not load_task("ring_walk").metrics_accumulator(1).floats
