"""Forward kinematics as one compiled kernel over rows (numba, through
:mod:`davinci_sim.kinematics.jit`): the law of :mod:`~davinci_sim.kinematics.fk`, for one
configuration (the live arm, a batch of one) and for many (the study's trials, the batched
API), with the same arithmetic row by row, so a row's bits do not depend on the batch.

:func:`tip_poses` runs :func:`tip_pose_row` (also called by other kernels, e.g. the PSM IK's
FK check) on each row: the tip pose, the joint frames and, if asked, the spatial Jacobian.
Compiled, one arm's pose and Jacobian cost ~1 µs instead of ~25 µs of Python float
arithmetic (the fallback without numba: the same function, the same bits). Chain constants
come packed as arrays (:func:`pack`): per joint ``revolute`` (1.0/0.0), ``cos α``, ``sin α``,
``a``, ``θ0`` and ``d0`` (rows of ``links``, (6, n)), the convention, and the tool transform.
"""

from __future__ import annotations

import math

import numpy as np

from davinci_sim.kinematics.jit import helper, jit, warm


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
def tip_poses(links, modified, tool, tool_is_identity, Q, T, J, jacobian, F):
    """For each row ``Q[r]`` (n,): ``T_base_tip`` (links · tool) into ``T[r]`` (4, 4) and, if
    ``jacobian``, the spatial Jacobian (6, n) into ``J[r]``; the joint frames ``T_base_i``
    (n, 12: r00..r22 row-major, px, py, pz) into ``F[r]`` when ``F`` has a row per
    configuration, else into the scratch ``F[0]``."""
    keep = F.shape[0] == Q.shape[0]
    for r in range(Q.shape[0]):
        f = F[r] if keep else F[0]
        tip_pose_row(links, modified, tool, tool_is_identity, Q[r], T[r], J[r], jacobian, f)


@helper
def tip_pose_row(links, modified, tool, tool_is_identity, q, T, J, jacobian, F):
    """One configuration ``q`` (n,): the tip pose into ``T`` (4, 4), the joint frames into
    ``F`` (n, 12) and, if ``jacobian``, the spatial Jacobian into ``J`` (6, n)."""
    n = q.shape[0]
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
    T, J, F = np.empty((1, 4, 4)), np.empty((1, 6, 1)), np.empty((1, 1, 12))
    tip_poses(np.zeros((6, 1)), True, np.eye(4), True, np.zeros((1, 1)), T, J, True, F)


warm(_warm_up)
