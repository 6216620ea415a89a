"""Rigid transforms: the inverse of one and of a stack."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from davinci_sim.geometry.se3 import invert_transform, transform


def test_the_inverse_of_a_stack_is_each_ones_inverse():
    rng = np.random.default_rng(3)
    Ts = np.array([transform(Rotation.random(random_state=k).as_matrix(), rng.normal(size=3))
                   for k in range(5)])  # fmt: skip
    inverses = invert_transform(Ts)
    assert inverses.shape == (5, 4, 4)
    for T, inverse in zip(Ts, inverses, strict=True):
        np.testing.assert_allclose(inverse, invert_transform(T), atol=1e-15)
        np.testing.assert_allclose(inverse @ T, np.eye(4), atol=1e-12)
        np.testing.assert_allclose(inverse, np.linalg.inv(T), atol=1e-12)  # (a reference)
