"""The camera teleoperation's geometry: the cross product and norms it uses are numpy's,
bit for bit (``geometry.floats.np_cross``, ``camera_control._norm``), so that the camera's
goals do not change with them."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from davinci_sim.console import camera_control as cc

# Any double, and the special values numpy's arithmetic passes through.
number = st.floats(allow_nan=True, allow_infinity=True, width=64)
vec = st.tuples(number, number, number).map(lambda v: np.array(v, dtype=float))


@settings(max_examples=300, deadline=None)
@given(vec)
def test_norm_is_numpys_bit_for_bit(v):
    with np.errstate(all="ignore"):
        expected = float(np.linalg.norm(v))
        got = cc._norm(v)
    assert got == expected or (np.isnan(got) and np.isnan(expected))


def _unit(v):
    return v / float(np.linalg.norm(v))


def _signed(a, b, axis):
    return math.atan2(float(np.cross(a, b) @ axis), float(a @ b))


def _motion(c0, up0, c, up, scale):
    """``camera_motion`` as written with numpy's cross and norm (the formulas before)."""
    return (
        -_signed(_unit(c0 * (1, 0, 1)), _unit(c * (1, 0, 1)), np.array([0.0, 1.0, 0.0])),
        _signed(_unit(c0 * (0, 1, 1)), _unit(c * (0, 1, 1)), np.array([1.0, 0.0, 0.0])),
        scale * (float(np.linalg.norm(c0)) - float(np.linalg.norm(c))),
        -_signed(_unit(up0 * (1, 1, 0)), _unit(up * (1, 1, 0)), np.array([0.0, 0.0, 1.0])),
    )


def test_hands_geometry_and_motion_are_those_of_numpys_cross():
    """The geometry the teleoperation anchors on and the camera motion it sends, as
    ``np.cross`` gave them (the formulas of the module, with numpy's product)."""
    rng = np.random.default_rng(7)
    for _ in range(200):
        left, right = rng.normal(0, 0.1, 3), rng.normal(0, 0.1, 3)
        left[2] -= 0.4
        right[2] -= 0.4
        g = cc.hands_geometry(left, right)
        lr, c = right - left, 0.5 * (left + right)
        up = np.cross(lr, c)
        up = up / np.linalg.norm(up)
        side = np.cross(c, up)
        side = side / np.linalg.norm(side)
        assert g.up.tobytes() == up.tobytes() and g.side.tobytes() == side.tobytes()
        g2 = cc.hands_geometry(left + rng.normal(0, 0.01, 3), right + rng.normal(0, 0.01, 3))
        assert cc.camera_motion(g, g2, 0.2) == _motion(g.center, g.up, g2.center, g2.up, 0.2)
        axis = rng.normal(size=3)
        a, b = rng.normal(size=3), rng.normal(size=3)
        expected = math.atan2(float(np.cross(a, b) @ axis), float(a @ b))
        assert cc.signed_angle(a, b, axis) == expected
