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
@example(np.array([0.0, 0.0, np.nan]), np.array([0.0, np.nan, 0.0]))  # (NaNs' sign bits)
def test_cross_is_numpys_bit_for_bit(a, b):
    with np.errstate(all="ignore"):
        expected = np.cross(a, b)
        got = np_cross(a, b)
        rows = np_cross(np.stack([a, b, a]), np.stack([b, b, a]))
        expected_rows = np.cross(np.stack([a, b, a]), np.stack([b, b, a]))
    assert got.dtype == expected.dtype and got.shape == (3,)
    assert np.array_equal(got, expected, equal_nan=True)
    # −0.0 as numpy's; a NaN's sign bit is no value (nan·nan's differs between the two
    # orders of the same products: hypothesis found a = (0, 0, nan), b = (0, nan, 0))
    real = ~np.isnan(expected)
    assert np.signbit(got[real]).tolist() == np.signbit(expected[real]).tolist()
    assert rows.shape == (3, 3) and np.array_equal(rows, expected_rows, equal_nan=True)
    real = ~np.isnan(expected_rows)
    assert np.signbit(rows[real]).tolist() == np.signbit(expected_rows[real]).tolist()
