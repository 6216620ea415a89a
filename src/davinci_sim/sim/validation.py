"""Checks shared by every command: finite values, lengths, joint limits, pose matrices.

Each returns an error message, or ``""`` when the input is valid, so the arm can refuse a
command on its error channel without raising.
"""

from __future__ import annotations

import numpy as np


def as_vector(value, n: int, what: str) -> tuple[np.ndarray | None, str]:
    """``value`` as a float vector of length ``n``, or ``(None, message)``."""
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return None, f"{what} must be a sequence of {n} numbers, got {value!r}"
    if v.ndim != 1 or v.shape[0] != n:
        return None, f"{what} must have {n} values, got shape {v.shape}"
    if not np.all(np.isfinite(v)):
        return None, f"{what} contains NaN or inf: {v.tolist()}"
    return v, ""


def check_limits(q: np.ndarray, qmin: np.ndarray, qmax: np.ndarray, names, what: str) -> str:
    """Message naming the first joint outside [qmin, qmax], or ``""``."""
    bad = np.flatnonzero((q < qmin - 1e-9) | (q > qmax + 1e-9))
    if bad.size == 0:
        return ""
    i = int(bad[0])
    return (
        f"{what}: joint {names[i]!r} = {q[i]:.6g} is outside its limits "
        f"[{qmin[i]:.6g}, {qmax[i]:.6g}]"
    )


def as_transform(value, what: str) -> tuple[np.ndarray | None, str]:
    """``value`` as a proper 4x4 homogeneous transform (orthonormal rotation), or a message."""
    try:
        T = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return None, f"{what} must be a 4x4 transform, got {value!r}"
    if T.shape != (4, 4):
        return None, f"{what} must be a 4x4 transform, got shape {T.shape}"
    if not np.all(np.isfinite(T)):
        return None, f"{what} contains NaN or inf"
    R = T[:3, :3]
    if np.max(np.abs(R.T @ R - np.eye(3))) > 1e-6 or np.linalg.det(R) < 0:
        return None, f"{what}: rotation part is not a proper rotation matrix"
    if np.max(np.abs(T[3] - (0, 0, 0, 1))) > 1e-12:
        return None, f"{what}: last row must be (0, 0, 0, 1)"
    return T, ""
