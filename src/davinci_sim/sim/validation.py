"""Checks shared by every command: finite values, lengths, joint limits, pose matrices.

Each returns an error message, or ``""`` when the input is valid, so the arm can refuse a
command on its error channel without raising.
"""

from __future__ import annotations

import math
import operator

import numpy as np


def as_vector(value, n: int, what: str) -> tuple[np.ndarray | None, str]:
    """``value`` as a float vector of length ``n``, or ``(None, message)``."""
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):  # OverflowError: a 400-digit integer
        return None, f"{what} must be a sequence of {n} numbers, got {short_repr(value)}"
    if v.ndim != 1 or v.shape[0] != n:
        return None, f"{what} must have {n} values, got shape {v.shape}"
    if not np.isfinite(v).all():
        return None, f"{what} contains NaN or inf: {v.tolist()}"
    return v, ""


def clip_goal(q, qmin, qmax, names, what: str) -> tuple[np.ndarray | None, str]:
    """Joint goal ``q`` (rad or m) clipped to [``qmin``, ``qmax``] as the dVRK's ``clip_jp``
    clips every goal of a homed arm (``move_jp``, ``servo_jp``, the IK results of
    ``move_cp``/``servo_cp``), or ``(None, message)`` for a goal beyond
    ±:data:`MAX_JOINT_VALUE`: that is a wrong value, not a place past a limit."""
    q = np.asarray(q, dtype=float)
    if not (np.abs(q) <= MAX_JOINT_VALUE).all():  # NaN too
        i = int(np.flatnonzero(~(np.abs(q) <= MAX_JOINT_VALUE))[0])
        return None, (
            f"{what}: joint {names[i]!r} = {q[i]:.6g} is outside its limits by far (beyond "
            f"±{MAX_JOINT_VALUE:g} rad or m; goals nearer are clipped to the limits)"
        )
    return np.minimum(np.maximum(q, qmin), qmax), ""


#: Largest coordinate of a pose's position, m: every frame of the system (cart, camera,
#: RCM, HRSV) is within a few metres of every other, so a goal beyond this is an error, not
#: a place (and a value like 1e300 overflows the IK to NaN).
MAX_TRANSLATION_M = 10.0


def as_transform(value, what: str) -> tuple[np.ndarray | None, str]:
    """``value`` as a proper 4x4 homogeneous transform (orthonormal rotation), or a message."""
    try:
        T = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        return None, f"{what} must be a 4x4 transform, got {short_repr(value)}"
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


#: A command this many times beyond the dVRK's own limit of its quantity (a joint's ``ftmax``,
#: dvrk.md 1.1 to 1.5) is refused as absurd; below it the value is clamped to the limit, as
#: the dVRK's joint controllers clamp efforts.
ABSURD_FACTOR = 10.0
#: Largest speeds of a twist (an arm's feed-forward, a remote handle's velocity): m/s and
#: rad/s. The dVRK's trajectory limits are at most 0.2 m/s (insertion) and 6π rad/s (PSM
#: wrist, MTM roll), dvrk.md 1.9; a hand moves the MTM handle at a few m/s at most.
MAX_LINEAR_SPEED = 10.0
MAX_ANGULAR_SPEED = 100.0
#: Largest force (N) and torque (N·m) of a Cartesian wrench command (``body/servo_cf``,
#: ``spatial/servo_cf``): ten times what a dVRK arm can apply at its tip. The PSM's joint
#: limits (ftmax 3.3 N·m at ~0.1 m, 9.9 N insertion, dvrk.md 1.2) give some 10 N; the MTM's
#: motors a few N at the handle (dvrk.md 1.5). The joints still clamp to their ftmax.
MAX_FORCE = 100.0
MAX_TORQUE = 10.0
#: Largest joint value of a kinematics query (``forward_kinematics``, an IK seed), rad or m:
#: no joint turns more than a few turns or slides more than a metre; 1e300 overflows the pose.
MAX_JOINT_VALUE = 1e3


def check_bound(values, bound, names, what: str, unit: str) -> str:
    """Message naming the first of ``values`` whose magnitude is over ``bound`` (a number,
    or one per value; NaN counts as over), or ``""``."""
    # Floats: this runs on streaming commands (servo_cp's twist, servo_cf), at 1 kHz.
    v = values.tolist() if isinstance(values, np.ndarray) else [float(x) for x in values]
    if isinstance(bound, np.ndarray):
        bound = bound.tolist()
    b = [float(bound)] * len(v) if isinstance(bound, int | float) else bound
    if len(v) == len(b) and all(map(operator.le, map(abs, v), b)):  # the common case
        return ""
    for i, (x, limit) in enumerate(zip(v, b, strict=True)):
        if not abs(x) <= limit:
            return f"{what}[{i}] ({names[i]}) = {x:.4g} is over {limit:.4g} {unit}"
    return ""


_TWIST_NAMES = ("vx", "vy", "vz", "wx", "wy", "wz")
_TWIST_BOUND = (MAX_LINEAR_SPEED,) * 3 + (MAX_ANGULAR_SPEED,) * 3
_WRENCH_NAMES = ("fx", "fy", "fz", "tx", "ty", "tz")
_WRENCH_BOUND = (MAX_FORCE,) * 3 + (MAX_TORQUE,) * 3


def as_twist(value, what: str = "twist") -> tuple[np.ndarray | None, str]:
    """``value`` as a twist (6: m/s then rad/s) within :data:`MAX_LINEAR_SPEED` and
    :data:`MAX_ANGULAR_SPEED`, or ``(None, message)``."""
    v, msg = as_vector(value, 6, what)
    if v is None:
        return None, msg
    msg = check_bound(v, _TWIST_BOUND, _TWIST_NAMES, what, "(m/s, rad/s)")
    return (None, msg) if msg else (v, "")


def as_wrench(value, what: str = "wrench") -> tuple[np.ndarray | None, str]:
    """``value`` as a wrench (6: N then N·m) within :data:`MAX_FORCE` and :data:`MAX_TORQUE`,
    or ``(None, message)``."""
    v, msg = as_vector(value, 6, what)
    if v is None:
        return None, msg
    msg = check_bound(v, _WRENCH_BOUND, _WRENCH_NAMES, what, "(N, N·m)")
    return (None, msg) if msg else (v, "")


def as_bool(value, what: str) -> tuple[bool | None, str]:
    """``value`` as a bool (a bool, or the integers 0 and 1 as ROS and JSON clients send),
    or ``(None, message)``: a string such as ``"false"`` is not silently true."""
    if isinstance(value, bool | np.bool_):
        return bool(value), ""
    if isinstance(value, int | np.integer) and value in (0, 1):
        return bool(value), ""
    return None, f"{what} must be true or false, got {short_repr(value)}"


def as_number(value, what: str) -> tuple[float | None, str]:
    """``value`` as a finite float (not a bool), or ``(None, message)``."""
    if isinstance(value, bool | np.bool_):
        return None, f"{what} must be a number, got {value!r}"
    try:
        x = float(value)
    except (TypeError, ValueError, OverflowError):
        return None, f"{what} must be a number, got {short_repr(value)}"
    if not math.isfinite(x):
        return None, f"{what} is {x!r}"
    return x, ""


def short_repr(value, limit: int = 200) -> str:
    """``repr(value)`` cut to ``limit`` characters (a bad value may be megabytes long)."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit]}… ({len(text)} characters)"
