"""numpy's elementwise rules on Python floats: what a law written on floats (a compiled row,
one trial's metrics) uses to give the bits its numpy form gives.

Plain functions; a compiled kernel wraps them with :func:`davinci_sim.kinematics.jit.helper`.
"""

from __future__ import annotations

import math


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
