"""Pose and spatial Jacobian of one configuration as a compiled kernel (numba, through
:mod:`davinci_sim.kinematics.jit`).

The same arithmetic, operation for operation, as the float path of
:mod:`~davinci_sim.kinematics.fk` (``_frames_floats``, ``_apply_tool``,
``_jacobian_spatial_floats``), so the results are the same bits; compiled, one arm's pose
and Jacobian cost ~1 µs instead of ~25 µs of Python float arithmetic, and the 1 kHz loop
evaluates them for every teleoperated arm every tick.

One kernel, :func:`tip_pose_and_jacobian`. Chain constants come packed as arrays
(:func:`pack`): per joint ``revolute`` (1.0/0.0), ``cos α``, ``sin α``, ``a``, ``θ0`` and
``d0`` (rows of ``links``, (6, n)), the convention, and the tool transform.
"""

from __future__ import annotations

import math

import numpy as np

from davinci_sim.kinematics.jit import helper, jit


def pack(links, modified: bool, R_tool, p_tool, tool_is_identity: bool) -> tuple:
    """The kernels' arguments for one chain (``fk._ChainConsts``'s fields)."""
    table = np.array(
        [[1.0 if lk.revolute else 0.0, lk.ca, lk.sa, lk.a, lk.theta0, lk.d0] for lk in links],
        dtype=float,
    ).reshape(-1, 6)
    tool = np.eye(4)
    tool[:3, :3] = np.array(R_tool, dtype=float)
    tool[:3, 3] = np.array(p_tool, dtype=float)
    return np.ascontiguousarray(table.T), bool(modified), tool, bool(tool_is_identity)


@jit
def tip_pose_and_jacobian(links, modified, tool, tool_is_identity, q, T, J, jacobian):
    """``T_base_tip`` (links · tool) of ``q`` into ``T`` (4, 4) and, if ``jacobian``, the
    spatial Jacobian (6, n) into ``J``."""
    tip_pose_row(links, modified, tool, tool_is_identity, q, T, J, jacobian)


@helper
def tip_pose_row(links, modified, tool, tool_is_identity, q, T, J, jacobian):
    """The law of :func:`tip_pose_and_jacobian`, callable from other kernels (the PSM IK's
    FK check)."""
    n = q.shape[0]
    F = np.empty((n, 12))  # T_base_i of each joint: r00..r22 row-major, px, py, pz
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
    px = 0.0
    py = 0.0
    pz = 0.0
    for i in range(n):
        if links[0, i] != 0.0:
            th = links[4, i] + q[i]
            d = links[5, i]
        else:
            th = links[4, i]
            d = links[5, i] + q[i]
        ct = math.cos(th)
        st = math.sin(th)
        ca = links[1, i]
        sa = links[2, i]
        a = links[3, i]
        if modified:
            px += a * r00
            py += a * r10
            pz += a * r20
            r01, r02 = ca * r01 + sa * r02, ca * r02 - sa * r01
            r11, r12 = ca * r11 + sa * r12, ca * r12 - sa * r11
            r21, r22 = ca * r21 + sa * r22, ca * r22 - sa * r21
            r00, r01 = ct * r00 + st * r01, ct * r01 - st * r00
            r10, r11 = ct * r10 + st * r11, ct * r11 - st * r10
            r20, r21 = ct * r20 + st * r21, ct * r21 - st * r20
            px += d * r02
            py += d * r12
            pz += d * r22
        else:
            r00, r01 = ct * r00 + st * r01, ct * r01 - st * r00
            r10, r11 = ct * r10 + st * r11, ct * r11 - st * r10
            r20, r21 = ct * r20 + st * r21, ct * r21 - st * r20
            px += d * r02 + a * r00
            py += d * r12 + a * r10
            pz += d * r22 + a * r20
            r01, r02 = ca * r01 + sa * r02, ca * r02 - sa * r01
            r11, r12 = ca * r11 + sa * r12, ca * r12 - sa * r11
            r21, r22 = ca * r21 + sa * r22, ca * r22 - sa * r21
        F[i, 0] = r00
        F[i, 1] = r01
        F[i, 2] = r02
        F[i, 3] = r10
        F[i, 4] = r11
        F[i, 5] = r12
        F[i, 6] = r20
        F[i, 7] = r21
        F[i, 8] = r22
        F[i, 9] = px
        F[i, 10] = py
        F[i, 11] = pz
    if not tool_is_identity:
        t00, t01, t02, tx = tool[0, 0], tool[0, 1], tool[0, 2], tool[0, 3]
        t10, t11, t12, ty = tool[1, 0], tool[1, 1], tool[1, 2], tool[1, 3]
        t20, t21, t22, tz = tool[2, 0], tool[2, 1], tool[2, 2], tool[2, 3]
        px, py, pz = (
            px + r00 * tx + r01 * ty + r02 * tz,
            py + r10 * tx + r11 * ty + r12 * tz,
            pz + r20 * tx + r21 * ty + r22 * tz,
        )
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = (
            r00 * t00 + r01 * t10 + r02 * t20,
            r00 * t01 + r01 * t11 + r02 * t21,
            r00 * t02 + r01 * t12 + r02 * t22,
            r10 * t00 + r11 * t10 + r12 * t20,
            r10 * t01 + r11 * t11 + r12 * t21,
            r10 * t02 + r11 * t12 + r12 * t22,
            r20 * t00 + r21 * t10 + r22 * t20,
            r20 * t01 + r21 * t11 + r22 * t21,
            r20 * t02 + r21 * t12 + r22 * t22,
        )
    T[0, 0], T[0, 1], T[0, 2], T[0, 3] = r00, r01, r02, px
    T[1, 0], T[1, 1], T[1, 2], T[1, 3] = r10, r11, r12, py
    T[2, 0], T[2, 1], T[2, 2], T[2, 3] = r20, r21, r22, pz
    T[3, 0], T[3, 1], T[3, 2], T[3, 3] = 0.0, 0.0, 0.0, 1.0
    if not jacobian:
        return
    tx, ty, tz = T[0, 3], T[1, 3], T[2, 3]
    for i in range(q.shape[0]):
        # Modified DH: joint i acts about z of frame i; standard DH: of frame i-1.
        if modified:
            zx, zy, zz, ox, oy, oz = F[i, 2], F[i, 5], F[i, 8], F[i, 9], F[i, 10], F[i, 11]
        elif i == 0:
            zx, zy, zz, ox, oy, oz = 0.0, 0.0, 1.0, 0.0, 0.0, 0.0
        else:
            j = i - 1
            zx, zy, zz, ox, oy, oz = F[j, 2], F[j, 5], F[j, 8], F[j, 9], F[j, 10], F[j, 11]
        if links[0, i] != 0.0:
            rx, ry, rz = tx - ox, ty - oy, tz - oz
            J[0, i] = zy * rz - zz * ry
            J[1, i] = zz * rx - zx * rz
            J[2, i] = zx * ry - zy * rx
            J[3, i], J[4, i], J[5, i] = zx, zy, zz
        else:
            J[0, i], J[1, i], J[2, i] = zx, zy, zz
            J[3, i], J[4, i], J[5, i] = 0.0, 0.0, 0.0


def _warm_up() -> None:
    """Compile (or load from the cache) at import, with the one signature the callers use
    (C-contiguous float arrays, bools): never in the middle of a 1 kHz loop."""
    T, J = np.empty((4, 4)), np.empty((6, 1))
    tip_pose_and_jacobian(np.zeros((6, 1)), True, np.eye(4), True, np.zeros(1), T, J, True)


_warm_up()
