"""The wrench clamp every MTM wrench goes through: magnitude and rate of change."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from davinci_sim.devices.safety import WrenchLimiter, WrenchLimits, clamp_wrench

LIMITS = WrenchLimits(max_force=5.0, max_torque=0.1, max_force_rate=1000.0, max_torque_rate=10.0)
vec6 = st.lists(st.floats(-100, 100), min_size=6, max_size=6).map(np.array)


def test_magnitude_clamp_keeps_the_direction():
    w, clamped = clamp_wrench(
        [30.0, 40.0, 0.0, 0.0, 0.0, 0.2], [3.0, 4.0, 0.0, 0.0, 0.0, 0.1], LIMITS, 1.0
    )
    np.testing.assert_allclose(w, [3.0, 4.0, 0.0, 0.0, 0.0, 0.1])
    assert clamped


def test_rate_clamp_moves_towards_the_request_by_rate_times_dt():
    w, clamped = clamp_wrench([4.0, 0, 0, 0, 0, 0], np.zeros(6), LIMITS, 0.001)
    np.testing.assert_allclose(w, [1.0, 0, 0, 0, 0, 0])
    assert clamped
    w, clamped = clamp_wrench([0.5, 0, 0, 0, 0, 0.001], np.zeros(6), LIMITS, 0.001)
    np.testing.assert_allclose(w, [0.5, 0, 0, 0, 0, 0.001])
    assert not clamped


@given(vec6, vec6, st.floats(1e-4, 0.01))
def test_output_is_within_the_limits_and_the_rate(request, previous, dt):
    magnitude_only = WrenchLimits(
        max_force=5.0, max_torque=0.1, max_force_rate=math.inf, max_torque_rate=math.inf
    )
    prev, _ = clamp_wrench(previous, np.zeros(6), magnitude_only, 1.0)
    w, _ = clamp_wrench(request, prev, LIMITS, dt)
    assert np.linalg.norm(w[:3]) <= 5.0 + 1e-9 and np.linalg.norm(w[3:]) <= 0.1 + 1e-12
    assert np.linalg.norm(w[:3] - prev[:3]) <= 1000.0 * dt + 1e-9
    assert np.linalg.norm(w[3:] - prev[3:]) <= 10.0 * dt + 1e-12


def test_limiter_ramps_and_resets():
    limiter = WrenchLimiter(LIMITS, dt=0.001)
    outs = [limiter.limit([10.0, 0, 0, 0, 0, 0])[0] for _ in range(10)]
    np.testing.assert_allclose(outs, [1, 2, 3, 4, 5, 5, 5, 5, 5, 5])
    limiter.reset()
    assert limiter.limit([10.0, 0, 0, 0, 0, 0])[0] == pytest.approx(1.0)


@pytest.mark.parametrize("bad", [[np.nan] * 6, [0.0] * 5, "force", [[0.0] * 6]])
def test_bad_wrenches_raise_and_leave_the_limiter_unchanged(bad):
    limiter = WrenchLimiter(LIMITS)
    limiter.limit([0.5, 0, 0, 0, 0, 0])
    with pytest.raises(ValueError):
        limiter.limit(bad)
    np.testing.assert_allclose(limiter.previous, [0.5, 0, 0, 0, 0, 0])


def test_limits_are_validated():
    for field in ("max_force", "max_torque", "max_force_rate", "max_torque_rate"):
        for bad in (0.0, -1.0, float("nan")):
            with pytest.raises(ValueError, match=field):
                WrenchLimits(**{field: bad})
    assert WrenchLimits(max_force_rate=math.inf).max_force_rate == math.inf
    with pytest.raises(ValueError, match="dt"):
        clamp_wrench(np.zeros(6), np.zeros(6), LIMITS, 0.0)


def test_the_compiled_clamp_is_the_python_law_bit_for_bit():
    """The kernel of clamp_wrench/clamp_wrenches gives the same bits compiled (numba) and as
    plain Python (the fallback), and a device alone gets the row it gets in a batch."""
    from davinci_sim.devices.safety import _clamp_rows, clamp_wrenches

    rng = np.random.default_rng(3)
    w = rng.normal(scale=8.0, size=(64, 6))
    prev = rng.normal(scale=2.0, size=(64, 6))
    args = (LIMITS.max_force, LIMITS.max_torque, LIMITS.max_force_rate * 1e-3,
            LIMITS.max_torque_rate * 1e-3)  # fmt: skip
    compiled, python = np.empty_like(w), np.empty_like(w)
    _clamp_rows(w, prev, *args, compiled)
    _clamp_rows.py_func(w, prev, *args, python)
    np.testing.assert_array_equal(compiled, python)
    np.testing.assert_array_equal(clamp_wrenches(w, prev, LIMITS, 1e-3), compiled)
    for i in (0, 17, 63):
        alone, _ = clamp_wrench(w[i], prev[i], LIMITS, 1e-3)
        np.testing.assert_array_equal(alone, compiled[i])


def test_limit_checked_is_limit_without_the_check():
    """The device's 1 kHz path (a wrench its servo_cf already checked) gives the same
    wrenches, the same ``active`` flags and the same memory as the checked ``limit``."""
    rng = np.random.default_rng(11)
    a, b = WrenchLimiter(WrenchLimits()), WrenchLimiter(WrenchLimits())
    for _ in range(500):
        w = rng.normal(0, 3, 6) * rng.choice([0.0, 0.1, 1.0, 10.0])
        out_a, out_b = a.limit(w), b.limit_checked(w)
        np.testing.assert_array_equal(out_a, out_b, strict=True)
        assert a.active == b.active
        np.testing.assert_array_equal(a.previous, b.previous, strict=True)
    with pytest.raises(ValueError):
        a.limit(np.full(6, np.nan))  # the public limit still refuses
