"""``geometry.floats``: numpy's rules on floats give numpy's bits."""

from __future__ import annotations

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from davinci_sim.geometry.floats import np_cross

# Any double, and the special values numpy's arithmetic passes through.
number = st.floats(allow_nan=True, allow_infinity=True, width=64)
vec = st.tuples(number, number, number).map(lambda v: np.array(v, dtype=float))


@settings(max_examples=500, deadline=None)
@given(vec, vec)
@example(np.array([0.1, 0.2, 0.3]), np.array([0.1, 0.2, 0.3]))  # (parallel: zero)
@example(np.array([-0.0, 0.0, 1e-300]), np.array([1e300, -1e-300, 0.0]))  # signs, range
def test_cross_is_numpys_bit_for_bit(a, b):
    with np.errstate(all="ignore"):
        expected = np.cross(a, b)
        got = np_cross(a, b)
        rows = np_cross(np.stack([a, b, a]), np.stack([b, b, a]))
        expected_rows = np.cross(np.stack([a, b, a]), np.stack([b, b, a]))
    assert got.dtype == expected.dtype and got.shape == (3,)
    assert np.array_equal(got, expected, equal_nan=True)
    assert np.signbit(got).tolist() == np.signbit(expected).tolist()  # (−0.0 as numpy's)
    assert rows.shape == (3, 3) and np.array_equal(rows, expected_rows, equal_nan=True)
    assert np.signbit(rows).tolist() == np.signbit(expected_rows).tolist()
