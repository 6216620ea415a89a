"""Shared geometry of the RCM arms (PSM, ECM): the first three links, as plain floats.

Both arms start with yaw, pitch (revolute, about axes through the RCM) and insertion along the
shaft (dvrk.md 1.2, 1.4). Rotations here are row-major 3x3 tuples of floats: at this size,
numpy call overhead costs more than the arithmetic.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from davinci_sim.geometry.so3 import mat3_mul
from davinci_sim.kinematics.jit import helper

helper(mat3_mul)  # called by tool_origin in compiled kernels


@helper
def tool_origin(
    goal: Sequence[float], R_tool_T: Sequence[float], p_tool: Sequence[float]
) -> tuple[tuple[float, ...], float, float, float]:
    """The last link's frame for a goal of the tool tip (``fk_tuple`` layout): its rotation
    R = R_goal·R_toolᵀ (row-major) and origin p = p_goal − R·p_tool, m."""
    R = mat3_mul(goal[:9], R_tool_T)
    tx, ty, tz = p_tool
    return (
        R,
        goal[9] - (R[0] * tx + R[1] * ty + R[2] * tz),
        goal[10] - (R[3] * tx + R[4] * ty + R[5] * tz),
        goal[11] - (R[6] * tx + R[7] * ty + R[8] * tz),
    )


@helper
def rxrz(ca: float, sa: float, th: float) -> tuple[float, ...]:
    """Rx(α)·Rz(θ), the rotation of a modified-DH link (dvrk.md 1.1)."""
    ct, st = math.cos(th), math.sin(th)
    return (ct, -st, 0.0, st * ca, ct * ca, -sa, st * sa, ct * sa, ca)


def shaft_angles(
    ca: tuple[float, ...], sa: tuple[float, ...], z: tuple[float, float, float]
) -> list[tuple[float, float]]:
    """All (θ₁, θ₂) with Rx(α₁)Rz(θ₁)Rx(α₂)Rz(θ₂)Rx(α₃)·ẑ = z (unit vector), exact for any α.

    Shared by the PSM and ECM closed forms (same first three links). Empty if unreachable.
    """
    n, th1a, th2a, th1b, th2b = shaft_angle_pairs(ca, sa, z[0], z[1], z[2])
    return [(th1a, th2a), (th1b, th2b)][:n]


@helper
def shaft_angle_pairs(ca, sa, zx: float, zy: float, zz: float):
    """:func:`shaft_angles` as ``(count, θ₁, θ₂, θ₁', θ₂')`` (count 0, 1 or 2 answers; the
    unused angles are 0): plain floats, so compiled kernels call it too."""
    vy, vz = -sa[2], ca[2]  # Rx(α₃)ẑ = (0, −sα₃, cα₃)
    wx = zx
    wy = ca[0] * zy + sa[0] * zz  # w = Rx(−α₁) z
    wz = -sa[0] * zy + ca[0] * zz
    # Rx(α₂)Rz(θ₂)v has z component sα₂·vy·cθ₂ + cα₂·vz, which must equal wz.
    den = sa[1] * vy
    if den == 0.0:
        return 0, 0.0, 0.0, 0.0, 0.0
    c2 = (wz - ca[1] * vz) / den
    if abs(c2) > 1.0:
        if abs(c2) > 1.0 + 1e-12:
            return 0, 0.0, 0.0, 0.0, 0.0
        c2 = math.copysign(1.0, c2)
    s2 = math.sqrt(max(0.0, 1.0 - c2 * c2))
    my = ca[1] * vy * c2 - sa[1] * vz  # m = Rx(α₂)Rz(θ₂)v, x and y
    base = math.atan2(wy, wx)
    th1a = base - math.atan2(my, -vy * s2)
    th2a = math.atan2(s2, c2)
    if not s2 > 0.0:
        return 1, th1a, th2a, 0.0, 0.0
    return 2, th1a, th2a, base - math.atan2(my, -vy * -s2), math.atan2(-s2, c2)
