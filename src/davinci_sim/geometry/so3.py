"""Rotation helpers on 3x3 matrices: angle, rotation vector (axis·angle), Rodrigues.

Pure float math, fast enough for the 1 kHz teleoperation and haptic paths (a few µs each).
Angles are in rad.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from davinci_sim.geometry.floats import det3


def rotation_angle(R) -> float:
    """Angle (rad, in [0, π]) of the rotation ``R`` (the axis-angle magnitude)."""
    c = 0.5 * (float(R[0][0]) + float(R[1][1]) + float(R[2][2]) - 1.0)
    return math.acos(max(-1.0, min(1.0, c)))


def angle_between(R_a, R_b) -> float:
    """Angle (rad) of ``R_aᵀ·R_b``: how far orientation ``b`` is from ``a``."""
    a = np.asarray(R_a, dtype=float).ravel().tolist()
    b = np.asarray(R_b, dtype=float).ravel().tolist()
    return angle_between_entries(a, b)


def angle_between_entries(a, b) -> float:
    """:func:`angle_between` of two rotations given by their 9 entries, row-major (lists
    or 1-D arrays): plain arithmetic in numba's subset of Python, so that a compiled law
    (the web console's wrist turn, ``console/chunk_kernel.py``) gets the same bits."""
    s = 0.0  # trace(AᵀB) = Σ A_ij B_ij, summed in order
    for i in range(9):
        s += a[i] * b[i]
    c = 0.5 * (s - 1.0)
    return math.acos(max(-1.0, min(1.0, c)))


def rotation_vector(R) -> np.ndarray:
    """Rotation vector ``axis·angle`` (3,) of ``R``; exact also near 0 and π."""
    (a, b, c), (d, e, f), (g, h, i) = np.asarray(R, dtype=float).tolist()
    return np.array(rotation_vector_floats(a, b, c, d, e, f, g, h, i))


def rotation_vector_floats(
    a: float, b: float, c: float, d: float, e: float, f: float, g: float, h: float, i: float
) -> tuple[float, float, float]:
    """:func:`rotation_vector` of the rotation with rows ``(a, b, c), (d, e, f), (g, h, i)``,
    on floats: plain arithmetic in numba's subset of Python, so compiled laws use this one
    function too (e.g. the hand's law, :mod:`davinci_sim.devices.hand`)."""
    cos = max(-1.0, min(1.0, 0.5 * (a + e + i - 1.0)))
    angle = math.acos(cos)
    sx, sy, sz = h - f, c - g, d - b
    s = math.sin(angle)
    if s > 1e-6:
        k = 0.5 * angle / s
        return sx * k, sy * k, sz * k
    if angle < 0.5:  # near 0: sin θ ≈ θ
        return 0.5 * sx, 0.5 * sy, 0.5 * sz
    # Near π: R ≈ 2·a·aᵀ − I; take the column of B = (R + I)/2 with the largest diagonal
    # element (the first on a tie).
    b00, b11, b22 = 0.5 * (a + 1.0), 0.5 * (e + 1.0), 0.5 * (i + 1.0)
    if b00 >= b11 and b00 >= b22:
        u, v, w, bii = b00, 0.5 * d, 0.5 * g, b00
    elif b11 >= b22:
        u, v, w, bii = 0.5 * b, b11, 0.5 * h, b11
    else:
        u, v, w, bii = 0.5 * c, 0.5 * f, b22, b22
    norm = math.sqrt(max(bii, 1e-300))
    u, v, w = u / norm, v / norm, w / norm
    if u * sx + v * sy + w * sz < 0:
        u, v, w = -u, -v, -w
    return u * angle, v * angle, w * angle


def rotation_from_vector(w) -> np.ndarray:
    """Rotation matrix of the rotation vector ``w`` (axis·angle, rad), by Rodrigues' formula."""
    return rotation_from_array(np.asarray(w, dtype=float))


def rotation_from_array(w) -> np.ndarray:
    """:func:`rotation_from_vector` of a float array ``w`` (3,), in numba's subset of
    Python, so that a compiled law (the web console's wrist turn,
    ``devices/hand_input_row.py``) gets the same bits: the norm is ``sqrt`` of BLAS's dot,
    as numpy's ``norm`` of a vector is, and the products ``@``."""
    angle = math.sqrt(np.dot(w, w))
    if angle < 1e-12:
        return np.eye(3)
    k = w / angle
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K)


def is_rotation(R, tolerance: float = 1e-6) -> bool:
    """True for a finite 3x3 orthonormal matrix with determinant +1."""
    r = np.asarray(R, dtype=float)
    if r.shape != (3, 3) or not np.isfinite(r).all():
        return False
    if not np.max(np.abs(r.T @ r - np.eye(3))) <= tolerance:
        return False
    # Orthonormal within the tolerance: the determinant is ±1, and its sign that of the
    # triple product (a few µs less than LAPACK's det, the same answer).
    return det3(*r.ravel().tolist()) > 0


def mat3_mul(A: Sequence[float], B: Sequence[float]) -> tuple[float, ...]:
    """A·B for row-major 3x3 tuples."""
    a0, a1, a2, a3, a4, a5, a6, a7, a8 = A
    b0, b1, b2, b3, b4, b5, b6, b7, b8 = B
    return (
        a0 * b0 + a1 * b3 + a2 * b6, a0 * b1 + a1 * b4 + a2 * b7, a0 * b2 + a1 * b5 + a2 * b8,
        a3 * b0 + a4 * b3 + a5 * b6, a3 * b1 + a4 * b4 + a5 * b7, a3 * b2 + a4 * b5 + a5 * b8,
        a6 * b0 + a7 * b3 + a8 * b6, a6 * b1 + a7 * b4 + a8 * b7, a6 * b2 + a7 * b5 + a8 * b8,
    )  # fmt: skip


def rotate_rows(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``R·v`` for each vector of ``v`` (..., 3), one rotation ``R`` (3, 3).

    Elementwise (three scaled columns summed in a fixed order), not a matrix product: a
    matrix product's rounding depends on its size in BLAS, and a law must give a study
    trial the same bits whatever the size of its batch (and the live arm, a batch of one).
    """
    if v.ndim == 1:  # one vector (the live arm): the same operations on floats, faster
        x, y, z = v.tolist()
        (a, b, c), (d, e, f), (g, h, i) = R.tolist()
        return np.array([x * a + y * b + z * c, x * d + y * e + z * f, x * g + y * h + z * i])
    return v[..., 0:1] * R[:, 0] + v[..., 1:2] * R[:, 1] + v[..., 2:3] * R[:, 2]


def rotate_pairs(R: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Both halves of 6-vectors (twists: linear then angular; wrenches: force then torque),
    ``w`` (..., 6), rotated by ``R`` (3, 3) (see :func:`rotate_rows`)."""
    if w.ndim == 1:  # one 6-vector: floats, as rotate_rows
        x, y, z, u, v, s = w.tolist()
        (a, b, c), (d, e, f), (g, h, i) = R.tolist()
        return np.array(
            [
                x * a + y * b + z * c,
                x * d + y * e + z * f,
                x * g + y * h + z * i,
                u * a + v * b + s * c,
                u * d + v * e + s * f,
                u * g + v * h + s * i,
            ]
        )
    return np.concatenate([rotate_rows(R, w[..., :3]), rotate_rows(R, w[..., 3:])], axis=-1)


def rpy_from_matrix(R) -> tuple[float, float, float]:
    """URDF/ROS ``(roll, pitch, yaw)`` (rad) of ``R = Rz(yaw)·Ry(pitch)·Rx(roll)`` (fixed axes
    x, then y, then z). At gimbal lock (pitch = ±π/2) roll is 0 and yaw carries the rest."""
    r = np.asarray(R, dtype=float)
    sp = max(-1.0, min(1.0, -float(r[2, 0])))
    # atan2 of sin and cos, not asin: asin loses half the digits near pitch = ±π/2 (~1e-8
    # rad, which the dVRK's ±90° link frames hit in the URDF's origins)
    pitch = math.atan2(-float(r[2, 0]), math.hypot(float(r[0, 0]), float(r[1, 0])))
    if abs(sp) < 1.0 - 1e-12:
        roll = math.atan2(float(r[2, 1]), float(r[2, 2]))
        yaw = math.atan2(float(r[1, 0]), float(r[0, 0]))
    else:  # cos(pitch) = 0: only yaw ∓ roll is defined
        roll = 0.0
        yaw = math.atan2(-float(r[0, 1]), float(r[1, 1]))
    return roll, pitch, yaw


def matrix_from_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``Rz(yaw)·Ry(pitch)·Rx(roll)``, the rotation of a URDF ``rpy`` (rad); inverse of
    :func:`rpy_from_matrix`."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )
