"""The numbers behind :mod:`davinci_sim.compat.kdl`, as KDL 1.5 computes them: pure
functions on numpy arrays (3-vectors, 3x3 rotation matrices), no classes.

KDL's own formulas are followed where they differ from the textbook ones, since scripts
see the difference: ``Quaternion`` does not normalise (a non-unit quaternion scales the
matrix), ``Rot2`` takes its axis as given, ``Norm`` returns 0 when the largest component
is below ``eps`` only if it is x (KDL's scaled norm), ``GetRotAngle`` tells the identity and
half turns apart with tolerances, ``GetQuaternion`` does not normalise. Angles in rad.
Arithmetic is IEEE's, as in C++: a matrix that is no rotation gives NaN or infinity where
KDL's would, not an exception (numpy scalars, warnings silenced).
"""

from __future__ import annotations

import functools
import math

import numpy as np

EPSILON = 1e-6
"""KDL's default tolerance (``Equal``, ``==``, ``Norm``, ``Normalize``, ``GetRotAngle``)."""


def _ieee(f):
    """``f`` with C++'s floating point: 0/0 NaN, x/0 infinity, sqrt(-1) NaN, no warning."""

    @functools.wraps(f)
    def wrapped(*args, **kwargs):
        with np.errstate(all="ignore"):
            return f(*args, **kwargs)

    return wrapped


def _f(a) -> np.ndarray:
    """Numbers as numpy floats (IEEE division by zero)."""
    return np.asarray(a, dtype=float)


# =========================================================================== vectors
@_ieee
def norm(v: np.ndarray, eps: float = EPSILON) -> float:
    """KDL's ``Vector::Norm``: scaled by the largest component to keep precision; 0 when x
    is the largest in magnitude and below ``eps`` (KDL's test for an exactly zero vector)."""
    v = _f(v)
    ax, ay, az = abs(v[0]), abs(v[1]), abs(v[2])
    if ax >= ay and ax >= az:
        if ax < eps:
            return 0.0
        return float(ax * np.sqrt(1.0 + (v[1] / v[0]) ** 2 + (v[2] / v[0]) ** 2))
    if ay > az and ay > ax:
        return float(ay * np.sqrt(1.0 + (v[0] / v[1]) ** 2 + (v[2] / v[1]) ** 2))
    return float(az * np.sqrt(1.0 + (v[0] / v[2]) ** 2 + (v[1] / v[2]) ** 2))


@_ieee
def normalized(v: np.ndarray, eps: float = EPSILON) -> tuple[np.ndarray, float]:
    """KDL's ``Vector::Normalize``: (unit vector, former norm); a norm (with the default
    tolerance, as KDL) below ``eps`` gives ((1, 0, 0), 0)."""
    n = norm(v)
    if n < eps:
        return np.array([1.0, 0.0, 0.0]), 0.0
    return _f(v) / n, float(n)


def matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """3x3 times 3x3 (or 3), each term summed left to right as KDL's C++ does: the same
    rounding, so that ties later (the branches of ``GetQuaternion``, ``GetRotAngle``) fall
    the same way (a BLAS product may round differently)."""
    if b.ndim == 1:
        return (a[:, 0] * b[0] + a[:, 1] * b[1]) + a[:, 2] * b[2]
    return (a[:, 0:1] * b[0:1, :] + a[:, 1:2] * b[1:2, :]) + a[:, 2:3] * b[2:3, :]


def dot(a: np.ndarray, b: np.ndarray) -> float:
    return float((a[0] * b[0] + a[1] * b[1]) + a[2] * b[2])


# =========================================================================== rotations
def rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """About the fixed x by ``roll``, then fixed y by ``pitch``, then fixed z by ``yaw``."""
    return matmul(matmul(rot_z(yaw), rot_y(pitch)), rot_x(roll))


def euler_zyz(alpha: float, beta: float, gamma: float) -> np.ndarray:
    return matmul(matmul(rot_z(alpha), rot_y(beta)), rot_z(gamma))


def quaternion(x: float, y: float, z: float, w: float) -> np.ndarray:
    """KDL's matrix of (x, y, z, w), not normalised: a quaternion of norm n gives n² times a
    rotation (a zero one, the zero matrix)."""
    x2, y2, z2, w2 = x * x, y * y, z * z, w * w
    return np.array([
        [w2 + x2 - y2 - z2, 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), w2 - x2 + y2 - z2, 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), w2 - x2 - y2 + z2],
    ])  # fmt: skip


def rot2(axis: np.ndarray, angle: float) -> np.ndarray:
    """KDL's ``Rot2``: cos·I + (1 - cos)·a·aᵀ + sin·[a×], ``axis`` taken as given (unit for a
    rotation)."""
    c, s = math.cos(angle), math.sin(angle)
    vt = (1.0 - c) * np.asarray(axis, dtype=float)  # (1 - cos)·a, then times a: KDL's order
    x, y, z = axis
    return np.array([
        [c + vt[0] * x, -(z * s) + vt[0] * y, y * s + vt[0] * z],
        [z * s + vt[0] * y, c + vt[1] * y, -(x * s) + vt[1] * z],
        [-(y * s) + vt[0] * z, x * s + vt[1] * z, c + vt[2] * z],
    ])  # fmt: skip


def rotation_vector_matrix(v: np.ndarray) -> np.ndarray:
    """The rotation about ``v`` by ``|v|`` rad (KDL's free ``Rot(Vector)``)."""
    axis, angle = normalized(v, 1e-10)
    return rot2(axis, angle)


@_ieee
def get_rpy(R: np.ndarray) -> tuple[float, float, float]:
    """(roll, pitch, yaw) of :func:`rpy`; within 1e-12 of pitch ±π/2, roll is 0."""
    pitch = math.atan2(-R[2, 0], math.sqrt(R[0, 0] ** 2 + R[1, 0] ** 2))
    if abs(pitch) > math.pi / 2 - 1e-12:
        return 0.0, pitch, math.atan2(-R[0, 1], R[1, 1])
    return math.atan2(R[2, 1], R[2, 2]), pitch, math.atan2(R[1, 0], R[0, 0])


def get_euler_zyz(R: np.ndarray) -> tuple[float, float, float]:
    """(alpha, beta, gamma) of :func:`euler_zyz`; with beta 0 or π (within 1e-12 of
    ``|R[2, 2]|`` = 1) gamma is 0."""
    if abs(R[2, 2]) > 1 - 1e-12:
        if R[2, 2] > 0:
            return math.atan2(R[1, 0], R[0, 0]), 0.0, 0.0
        return math.atan2(-R[1, 0], -R[0, 0]), math.pi, 0.0
    alpha = math.atan2(R[1, 2], R[0, 2])
    beta = math.atan2(math.sqrt(R[2, 0] ** 2 + R[2, 1] ** 2), R[2, 2])
    return alpha, beta, math.atan2(R[2, 1], -R[2, 0])


@_ieee
def get_quaternion(R: np.ndarray) -> tuple[float, float, float, float]:
    """(x, y, z, w) by the largest of trace and diagonal (w > 0 when the trace exceeds
    1e-12); not normalised."""
    R = _f(R)
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    if tr > 1e-12:
        s = 0.5 / np.sqrt(tr + 1.0)
        q = ((R[2, 1] - R[1, 2]) * s, (R[0, 2] - R[2, 0]) * s, (R[1, 0] - R[0, 1]) * s, 0.25 / s)
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        q = (0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s, (R[2, 1] - R[1, 2]) / s)
    elif R[1, 1] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
        q = ((R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s, (R[0, 2] - R[2, 0]) / s)
    else:
        s = 2.0 * np.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
        q = ((R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s, (R[1, 0] - R[0, 1]) / s)
    return tuple(float(v) for v in q)


@_ieee
def get_rot_angle(R: np.ndarray, eps: float = EPSILON) -> tuple[float, np.ndarray]:
    """(angle in [0, π], unit axis). A symmetric ``R`` (within ``eps``) is the identity
    (within 10·eps: angle 0, axis z) or a half turn, its axis from the largest diagonal
    term; otherwise the angle from the trace and the skew part, the axis the skew part."""
    R = _f(R)
    if (abs(R[0, 1] - R[1, 0]) < eps and abs(R[0, 2] - R[2, 0]) < eps
            and abs(R[1, 2] - R[2, 1]) < eps):  # fmt: skip
        eps2 = 10 * eps
        if (abs(R[0, 1] + R[1, 0]) < eps2 and abs(R[0, 2] + R[2, 0]) < eps2
                and abs(R[1, 2] + R[2, 1]) < eps2 and abs(np.trace(R) - 3) < eps2):  # fmt: skip
            return 0.0, np.array([0.0, 0.0, 1.0])
        xx, yy, zz = (R[0, 0] + 1) / 2, (R[1, 1] + 1) / 2, (R[2, 2] + 1) / 2
        xy, xz, yz = (R[0, 1] + R[1, 0]) / 4, (R[0, 2] + R[2, 0]) / 4, (R[1, 2] + R[2, 1]) / 4
        if xx > yy and xx > zz:
            x = np.sqrt(xx)
            axis = (x, xy / x, xz / x)
        elif yy > zz:
            y = np.sqrt(yy)
            axis = (xy / y, y, yz / y)
        else:
            z = np.sqrt(zz)
            axis = (xz / z, yz / z, z)
        return math.pi, np.array(axis, dtype=float)
    f = (np.trace(R) - 1) / 2
    skew_part = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    angle = math.atan2(norm(skew_part) / 2, f)
    return float(angle), normalized(skew_part)[0]


# =========================================================================== frames
def dh(a: float, alpha: float, d: float, theta: float) -> tuple[np.ndarray, np.ndarray]:
    """Standard Denavit–Hartenberg: RotZ(θ)·TransZ(d)·TransX(a)·RotX(α) as (R, p)."""
    return matmul(rot_z(theta), rot_x(alpha)), np.array(
        [a * math.cos(theta), a * math.sin(theta), d]
    )


def dh_craig1989(a: float, alpha: float, d: float, theta: float):
    """Modified (Craig) Denavit–Hartenberg: RotX(α)·TransX(a)·RotZ(θ)·TransZ(d) as (R, p)."""
    return matmul(rot_x(alpha), rot_z(theta)), np.array(
        [a, -math.sin(alpha) * d, math.cos(alpha) * d]
    )


# =========================================================================== text
def fmt(x: float) -> str:
    """One number as KDL prints it (C++ streams: 6 significant digits, width 12)."""
    return f"{x:12g}"


def vector_text(values) -> str:
    return "[" + ",".join(fmt(v) for v in values) + "]"


def rotation_text(R: np.ndarray) -> str:
    return "[" + ";\n ".join(",".join(fmt(v) for v in row) for row in R) + "]"
