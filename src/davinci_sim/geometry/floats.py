"""numpy's elementwise rules on Python floats: what a law written on floats (a compiled row,
one trial's metrics) uses to give the bits its numpy form gives.

Plain functions; a compiled kernel wraps them with :func:`davinci_sim.kinematics.jit.helper`
(all but :func:`np_cross`, numpy's cross product of 3-vectors or rows with its own
arithmetic, for Python code that takes one a tick).
"""

from __future__ import annotations

import math

import numpy as np


def np_minimum(a: float, b: float) -> float:
    """``np.minimum(a, b)``: NaN if either is; ``b`` on a tie (so ``-0.0`` against ``0.0``
    gives ``0.0``, as numpy does)."""
    return a if (a != a or a < b) else b


def np_maximum(a: float, b: float) -> float:
    """``np.maximum(a, b)``: NaN if either is; ``b`` on a tie."""
    return a if (a != a or a > b) else b


def norm3(x: float, y: float, z: float) -> float:
    """``np.linalg.norm`` of a row of three: its squares summed ``(x² + y²) + z²``, the order
    numpy's reduction sums a short row in."""
    return math.sqrt((x * x + y * y) + z * z)


def cross3(a0: float, a1: float, a2: float, b0: float, b1: float, b2: float
           ) -> tuple[float, float, float]:  # fmt: skip
    """The cross product of (a0, a1, a2) and (b0, b1, b2) with ``np.cross``'s arithmetic:
    each component one difference of two rounded products."""
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


def det3(a: float, b: float, c: float, d: float, e: float, f: float, g: float, h: float,
         i: float) -> float:  # fmt: skip
    """The determinant of the 3x3 with rows (a, b, c), (d, e, f), (g, h, i), as the triple
    product (row 0 against the cross product of rows 1 and 2): the sign LAPACK's gives for
    a matrix near orthonormal, without its factorisation."""
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)


def np_cross(a, b) -> np.ndarray:
    """``np.cross`` of 3-vectors ``a`` and ``b`` (3,) or rows (..., 3) with its arithmetic
    (each component one difference of two rounded products, ``a1·b2 − a2·b1``, ...: the same
    bits), without its axis handling, which costs ~15 µs a call; a pair of vectors on floats."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.shape == (3,) and b.shape == (3,):
        return np.array(cross3(*a.tolist(), *b.tolist()))
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0], out[..., 1], out[..., 2] = cross3(a0, a1, a2, b0, b1, b2)  # (elementwise)
    return out
