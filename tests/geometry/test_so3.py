"""``so3.is_rotation``: its determinant's sign from the triple product gives LAPACK's
answer (orthonormal within the tolerance: the determinant is ±1)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from davinci_sim.geometry import so3


def _reference(R: np.ndarray, tolerance: float = 1e-6) -> bool:
    """The rule as stated: finite, orthonormal within ``tolerance``, determinant +1."""
    if R.shape != (3, 3) or not np.isfinite(R).all():
        return False
    return bool(np.max(np.abs(R.T @ R - np.eye(3))) <= tolerance and np.linalg.det(R) > 0)


@settings(max_examples=300, deadline=None)
@given(
    st.tuples(*[st.floats(-1.0, 1.0)] * 3),
    st.floats(-np.pi, np.pi),
    st.booleans(),
    st.floats(0.0, 3e-6),
    st.integers(0, 8),
)
def test_is_rotation_agrees_with_the_determinant_rule(axis, angle, reflect, noise, entry):
    w = np.array(axis)
    R = so3.rotation_from_vector(w / max(np.linalg.norm(w), 1e-9) * angle)
    if reflect:
        R = R @ np.diag([1.0, 1.0, -1.0])  # orthonormal, determinant −1
    R = R.copy()
    R.flat[entry] += noise  # (past the tolerance for some)
    assert so3.is_rotation(R) == _reference(R)


def test_is_rotation_refuses_what_is_not_a_finite_3x3():
    assert not so3.is_rotation(np.eye(4))
    assert not so3.is_rotation(np.full((3, 3), np.nan))
    assert not so3.is_rotation(np.zeros((3, 3)))
    assert so3.is_rotation(np.eye(3))
