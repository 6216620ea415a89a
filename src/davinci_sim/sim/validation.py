"""Checks shared by every command: finite values, lengths, joint limits, pose matrices.

Each returns an error message, or ``""`` when the input is valid, so the arm can refuse a
command on its error channel without raising.
"""

from __future__ import annotations

import math

import numpy as np


def as_vector(value, n: int, what: str) -> tuple[np.ndarray | None, str]:
    """``value`` as a float vector of length ``n``, or ``(None, message)``."""
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return None, f"{what} must be a sequence of {n} numbers, got {value!r}"
    if v.ndim != 1 or v.shape[0] != n:
        return None, f"{what} must have {n} values, got shape {v.shape}"
    if not np.isfinite(v).all():
        return None, f"{what} contains NaN or inf: {v.tolist()}"
    return v, ""


def check_limits(q: np.ndarray, qmin: np.ndarray, qmax: np.ndarray, names, what: str) -> str:
    """Message naming the first joint outside [qmin, qmax], or ``""``."""
    # Floats: this runs on every streaming command, at 1 kHz.
    values, lo, hi = np.asarray(q).tolist(), np.asarray(qmin).tolist(), np.asarray(qmax).tolist()
    bad = [
        i
        for i, (x, a, b) in enumerate(zip(values, lo, hi, strict=True))
        if x < a - 1e-9 or x > b + 1e-9
    ]
    if not bad:
        return ""
    i = bad[0]
    return (
        f"{what}: joint {names[i]!r} = {q[i]:.6g} is outside its limits "
        f"[{qmin[i]:.6g}, {qmax[i]:.6g}]"
    )


#: Largest coordinate of a pose's position, m: every frame of the system (cart, camera,
#: RCM, HRSV) is within a few metres of every other, so a goal beyond this is an error, not
#: a place (and a value like 1e300 overflows the IK to NaN).
MAX_TRANSLATION_M = 10.0


def as_transform(value, what: str) -> tuple[np.ndarray | None, str]:
    """``value`` as a proper 4x4 homogeneous transform (orthonormal rotation), or a message."""
    try:
        T = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return None, f"{what} must be a 4x4 transform, got {value!r}"
    if T.shape != (4, 4):
        return None, f"{what} must be a 4x4 transform, got shape {T.shape}"
    # Float arithmetic: this check runs on every servo_cp, at 1 kHz.
    f = T.ravel().tolist()
    if not all(map(math.isfinite, f)):
        return None, f"{what} contains NaN or inf"
    c0, c1, c2 = (f[0], f[4], f[8]), (f[1], f[5], f[9]), (f[2], f[6], f[10])
    gram = (
        _dot(c0, c0) - 1.0,
        _dot(c1, c1) - 1.0,
        _dot(c2, c2) - 1.0,
        _dot(c0, c1),
        _dot(c0, c2),
        _dot(c1, c2),
    )
    det = _dot(c2, (c0[1] * c1[2] - c0[2] * c1[1], c0[2] * c1[0] - c0[0] * c1[2],
                    c0[0] * c1[1] - c0[1] * c1[0]))  # fmt: skip
    if max(map(abs, gram)) > 1e-6 or det < 0:
        return None, f"{what}: rotation part is not a proper rotation matrix"
    if max(abs(f[12]), abs(f[13]), abs(f[14]), abs(f[15] - 1.0)) > 1e-12:
        return None, f"{what}: last row must be (0, 0, 0, 1)"
    reach = max(abs(f[3]), abs(f[7]), abs(f[11]))
    if reach > MAX_TRANSLATION_M:
        return None, (
            f"{what}: position ({f[3]:.4g}, {f[7]:.4g}, {f[11]:.4g}) m is beyond "
            f"{MAX_TRANSLATION_M:g} m of its reference frame (no arm or console reaches it)"
        )
    return T, ""


def _dot(a, b) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
