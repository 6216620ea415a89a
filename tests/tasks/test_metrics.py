"""Repetition metrics on synthetic trajectories with known answers."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from davinci_sim.tasks import Sample
from davinci_sim.tasks.metrics import (
    PATH_METRICS,
    MetricsAccumulator,
    clutch_count,
    completion_time,
    deviation_error,
    deviation_max,
    deviation_rms,
    force_mean,
    force_peak,
    mean_speed,
    path_length,
    repetition_metrics,
    time_outside,
)

DT = 0.001


def straight_run(speed=0.02, offset=0.002, T=2.0):
    """Along x at constant speed, ``offset`` m beside a path on the x axis."""
    t = np.arange(0.0, T + DT / 2, DT)
    p = np.stack([speed * t, np.full_like(t, offset), np.zeros_like(t)], axis=1)
    return t, p, np.full_like(t, offset)


def test_straight_run_with_constant_offset():
    t, p, d = straight_run()
    m = np.ones(len(t), dtype=bool)
    assert deviation_error(d, m)[0] == pytest.approx(0.002)
    assert completion_time(t, m)[0] == pytest.approx(2.0)
    assert path_length(p, m)[0] == pytest.approx(0.04)
    assert mean_speed(p, t, m)[0] == pytest.approx(0.02)
    assert time_outside(d, t, m, tube_radius=0.001)[0] == pytest.approx(2.0)
    assert time_outside(d, t, m, tube_radius=0.003)[0] == 0.0


def test_sinusoidal_deviation():
    """‖φ‖ = A|sin ωt| over whole periods: mean 2A/π; outside r: 1 − (2/π)·asin(r/A) of the
    time."""
    t = np.arange(0.0, 4.0, DT)
    A, r = 0.004, 0.002
    d = A * np.abs(np.sin(2 * np.pi * 1.0 * t))
    m = np.ones(len(t), dtype=bool)
    assert deviation_error(d, m)[0] == pytest.approx(2 * A / np.pi, rel=1e-3)
    # (Rota's RMS: A/√2 over whole periods; Enayati's maximum: the amplitude)
    assert deviation_rms(d, m)[0] == pytest.approx(A / np.sqrt(2), rel=1e-3)
    assert deviation_max(d, m)[0] == pytest.approx(A, rel=1e-6)
    half = t < 2.0  # (the mask: the first two periods only)
    assert deviation_rms(d * (1 + (~half)), half)[0] == pytest.approx(A / np.sqrt(2), rel=1e-3)
    assert deviation_max(d * (1 + (~half)), half)[0] == pytest.approx(A, rel=1e-6)
    frac = 1 - 2 / np.pi * np.arcsin(r / A)
    T = completion_time(t, m)[0]
    assert time_outside(d, t, m, tube_radius=r)[0] == pytest.approx(frac * T, rel=2e-3)


def test_circle_length_and_speed():
    R, w = 0.01, 2 * np.pi * 0.5
    t = np.arange(0.0, 2.0 + DT / 2, DT)
    p = np.stack([R * np.cos(w * t), R * np.sin(w * t), 0 * t], axis=1)
    m = np.ones(len(t), dtype=bool)
    assert path_length(p, m)[0] == pytest.approx(2 * np.pi * R, rel=1e-6)
    assert mean_speed(p, t, m)[0] == pytest.approx(R * w, rel=1e-6)


def test_forces_and_clutches():
    f = np.zeros((8, 3))
    f[:, 1] = 1.0
    f[5] = [0.0, 3.0, 4.0]  # 5 N peak
    m = np.ones(8, dtype=bool)
    assert force_peak(f, m)[0] == 5.0
    assert force_mean(f, m)[0] == pytest.approx((7 + 5) / 8)
    c = np.array([0, 1, 1, 0, 1, 0, 0, 1], dtype=bool)
    assert clutch_count(c, m)[0] == 3
    assert clutch_count(np.array([1, 1, 0, 1]), np.ones(4, dtype=bool))[0] == 1


def test_masked_batch_equals_trials_one_by_one():
    """Samples outside each trial's window do not count; the batch gives each trial's own
    metrics."""
    rng = np.random.default_rng(4)
    n, K = 3, 400
    t = np.arange(K) * DT
    p = np.cumsum(rng.normal(0, 1e-4, (n, K, 3)), axis=1)
    d = np.abs(rng.normal(0.002, 0.001, (n, K)))
    f = rng.normal(0, 1, (n, K, 3))
    c = rng.random((n, K)) < 0.05
    m = np.zeros((n, K), dtype=bool)
    windows = [(0, 400), (50, 300), (120, 121)]
    for i, (a, b) in enumerate(windows):
        m[i, a:b] = True
    batch = repetition_metrics(t, p, d, f, c, m, tube_radius=0.002)
    for i, (a, b) in enumerate(windows):
        one = repetition_metrics(
            t[a:b],
            p[i, a:b],
            d[i, a:b],
            f[i, a:b],
            c[i, a:b],
            np.ones(b - a, bool),
            tube_radius=0.002,
        )
        for name, x, y in zip(batch._fields, batch, one, strict=True):
            np.testing.assert_allclose(x[i], y[0], err_msg=name, equal_nan=True)
    assert batch.samples.tolist() == [400, 250, 1]
    assert batch.completion_time[2] == 0.0 and math.isnan(batch.mean_speed[2])


def test_accumulator_matches_the_array_functions():
    rng = np.random.default_rng(7)
    n, K = 5, 600
    t = np.arange(K) * DT
    p = np.cumsum(rng.normal(0, 2e-4, (n, K, 3)), axis=1)
    d = np.abs(rng.normal(0.002, 0.001, (n, K)))
    f = rng.normal(0, 1, (n, K, 3))
    c = rng.random((n, K)) < 0.03
    m = np.zeros((n, K), dtype=bool)
    for i in range(n):
        a = rng.integers(0, 300)
        m[i, a : a + rng.integers(1, 300)] = True
    acc = MetricsAccumulator(PATH_METRICS, n, SimpleNamespace(tube_radius=0.0025))
    for k in range(K):
        acc.update(m[:, k], Sample.of(t[k], p[:, k], f[:, k], c[:, k]), {"distance": d[:, k]})
    got = acc.result()
    ref = repetition_metrics(t, p, d, f, c, m, tube_radius=0.0025)
    assert set(ref._fields) <= set(got._fields)  # every reference metric is declared
    for name, y in zip(ref._fields, ref, strict=True):
        x = got[name]
        np.testing.assert_allclose(x, y, err_msg=name, rtol=1e-9, atol=1e-12, equal_nan=True)
    acc.reset(np.arange(n) == 0)
    assert acc.result().samples[0] == 0 and acc.result().samples[1] == m[1].sum()


def test_shape_mismatch_is_refused():
    with pytest.raises(ValueError):
        deviation_error(np.zeros(5), np.ones(4, dtype=bool))


def test_the_path_metrics_are_declared_with_units_and_directions():
    from davinci_sim.tasks.metrics import Count, Metric

    names = [m.name for m in PATH_METRICS]
    assert len(set(names)) == len(names)
    units = {m.name: m.unit for m in PATH_METRICS}
    assert units["deviation_error"] == "m" and units["mean_speed"] == "m/s"
    assert all(m.description and m.better in ("lower", "higher", "neither") for m in PATH_METRICS)
    assert [m.name for m in PATH_METRICS if m.integer] == ["clutch_count", "samples"]
    with pytest.raises(ValueError, match="better"):
        Metric("x", "m", "smaller", "bad direction", Count())


def test_accumulator_rows_taken_keep_what_they_have():
    """take(rows) (the batch dropping ended trials) gives those trials' own metrics."""
    rng = np.random.default_rng(3)
    n, K = 4, 200
    p = np.cumsum(rng.normal(0, 2e-4, (n, K, 3)), axis=1)
    d = np.abs(rng.normal(0.002, 0.001, (n, K)))
    task = SimpleNamespace(tube_radius=0.002)
    full = MetricsAccumulator(PATH_METRICS, n, task)
    part = None
    for k in range(K):
        s = Sample.of(k * DT, p[:, k], p[:, k] * 100, rng.random(n) < 0.1)
        full.update(np.ones(n, bool), s, {"distance": d[:, k]})
        if k == 99:
            part = full.take([3, 1])
        elif part is not None:
            part.update(np.ones(2, bool), s.take([3, 1]), {"distance": d[[3, 1], k]})
    a, b = full.result(), part.result()
    for name in a._fields:
        np.testing.assert_array_equal(a[name][[3, 1]], b[name], err_msg=name)
