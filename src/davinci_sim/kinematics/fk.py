"""Forward kinematics and Jacobians of :class:`~davinci_sim.kinematics.chain.DHChain`.

Every function accepts one configuration (shape ``(n,)``) or a batch (shape ``(..., n)``)
and returns arrays with the same leading batch shape. Poses are 4x4 homogeneous transforms
``T_base_frame`` in m; the base is the chain's first frame (the RCM for PSM/ECM, dvrk.md
section 1.2).

Two evaluation paths give the same numbers (to rounding, ~1e-15):

* one configuration: scalar float arithmetic, compiled (:mod:`.fk_compiled`, numba), or plain
  ``math`` on Python floats when compiling is off or fails: the same operations, the same
  bits (numpy call overhead dominates for 4x4 matrices, and the 1 kHz loop evaluates every
  arm every tick);
* a batch: the rotation columns and the position are carried as arrays of shape ``(chunk,)``
  and composed elementwise, chunk by chunk, which keeps the temporaries in cache and avoids
  batched 4x4 ``matmul`` (15-20x faster: ~4.6M PSM poses/s on the 2-core dev machine).
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np

from davinci_sim.kinematics import fk_compiled
from davinci_sim.kinematics.chain import DHChain
from davinci_sim.kinematics.jit import ENABLED as _COMPILED

#: Rows per chunk of the batched FK: small enough for the ~30 live temporaries to stay in cache
#: (measured best between 2048 and 16384 rows on the 2-core dev machine).
_CHUNK = 8192


@dataclass(frozen=True)
class _LinkConsts:
    """Per-joint constants of the elementwise FK (dvrk.md 1.1)."""

    revolute: bool
    ca: float
    sa: float
    a: float
    theta0: float
    """Constant part of the angle: theta + offset (revolute) or theta (prismatic)."""
    d0: float
    """Constant part of the length: d (revolute) or d + offset (prismatic)."""


@dataclass(frozen=True)
class _ChainConsts:
    modified: bool
    links: tuple[_LinkConsts, ...]
    R_tool: tuple[tuple[float, float, float], ...]
    p_tool: tuple[float, float, float]
    tool_is_identity: bool
    packed: tuple = ()
    """The same constants as :func:`.fk_compiled.pack` arrays (the compiled kernels')."""


_CONSTS: weakref.WeakKeyDictionary[DHChain, _ChainConsts] = weakref.WeakKeyDictionary()


def _consts(chain: DHChain) -> _ChainConsts:
    c = _CONSTS.get(chain)
    if c is None:
        links = []
        for j in chain.joints:
            rev = j.is_revolute
            links.append(
                _LinkConsts(
                    revolute=rev,
                    ca=math.cos(j.alpha),
                    sa=math.sin(j.alpha),
                    a=float(j.a),
                    theta0=float(j.theta + j.offset) if rev else float(j.theta),
                    d0=float(j.d) if rev else float(j.d + j.offset),
                )
            )
        T = chain.T_last_tip
        modified = chain.convention == "modified"
        R_tool = tuple(tuple(float(x) for x in row) for row in T[:3, :3])
        p_tool = tuple(float(x) for x in T[:3, 3])
        identity = bool(np.array_equal(T, np.eye(4)))
        c = _ChainConsts(
            modified=modified,
            links=tuple(links),
            R_tool=R_tool,
            p_tool=p_tool,
            tool_is_identity=identity,
            packed=fk_compiled.pack(links, modified, R_tool, p_tool, identity),
        )
        _CONSTS[chain] = c
    return c


def _effective_theta_d(chain: DHChain, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # dvrk.md 1.1: revolute -> theta + offset + q; prismatic -> D + offset + q.
    p = chain._params  # type: ignore[attr-defined]
    rev = p["revolute"]
    theta = np.where(rev, p["theta"] + p["offset"] + q, p["theta"])
    d = np.where(rev, p["d"], p["d"] + p["offset"] + q)
    return theta, d


def _check_q(chain: DHChain, q: np.ndarray) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    if q.ndim == 0 or q.shape[-1] != chain.dof:
        raise ValueError(
            f"{chain.name}: expected joint array with last dimension {chain.dof}, got {q.shape}"
        )
    return q


def link_transforms(chain: DHChain, q: np.ndarray) -> np.ndarray:
    """The n link transforms ``T_{i-1}_{i}``, shape ``(..., n, 4, 4)`` (dvrk.md section 1.1)."""
    q = _check_q(chain, q)
    p = chain._params  # type: ignore[attr-defined]
    theta, d = _effective_theta_d(chain, q)
    ct, st = np.cos(theta), np.sin(theta)
    ca = np.broadcast_to(np.cos(p["alpha"]), ct.shape)
    sa = np.broadcast_to(np.sin(p["alpha"]), ct.shape)
    a = np.broadcast_to(p["a"], ct.shape)
    T = np.zeros((*q.shape, 4, 4))
    if chain.convention == "modified":
        # RotX(alpha) TransX(a) RotZ(theta) TransZ(d)
        T[..., 0, 0], T[..., 0, 1], T[..., 0, 3] = ct, -st, a
        T[..., 1, 0], T[..., 1, 1], T[..., 1, 2], T[..., 1, 3] = st * ca, ct * ca, -sa, -sa * d
        T[..., 2, 0], T[..., 2, 1], T[..., 2, 2], T[..., 2, 3] = st * sa, ct * sa, ca, ca * d
    else:
        # RotZ(theta) TransZ(d) TransX(a) RotX(alpha)
        T[..., 0, 0], T[..., 0, 1], T[..., 0, 2], T[..., 0, 3] = ct, -st * ca, st * sa, a * ct
        T[..., 1, 0], T[..., 1, 1], T[..., 1, 2], T[..., 1, 3] = st, ct * ca, -ct * sa, a * st
        T[..., 2, 1], T[..., 2, 2], T[..., 2, 3] = sa, ca, d
    T[..., 3, 3] = 1.0
    return T


# --- one configuration: plain floats --------------------------------------------------------


def _frames_floats(cc: _ChainConsts, q) -> list[tuple[float, ...]]:
    """``T_base_i`` for i = 1 … n as flat 12-tuples (r00..r22 row-major, px, py, pz)."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
    px = py = pz = 0.0
    out = []
    cos, sin = math.cos, math.sin
    for lk, qi in zip(cc.links, q, strict=True):
        if lk.revolute:
            th = lk.theta0 + qi
            d = lk.d0
        else:
            th = lk.theta0
            d = lk.d0 + qi
        ct, st = cos(th), sin(th)
        ca, sa, a = lk.ca, lk.sa, lk.a
        if cc.modified:
            # R·RotX(alpha)·TransX(a)·RotZ(theta)·TransZ(d), column by column.
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
            # R·RotZ(theta)·TransZ(d)·TransX(a)·RotX(alpha).
            r00, r01 = ct * r00 + st * r01, ct * r01 - st * r00
            r10, r11 = ct * r10 + st * r11, ct * r11 - st * r10
            r20, r21 = ct * r20 + st * r21, ct * r21 - st * r20
            px += d * r02 + a * r00
            py += d * r12 + a * r10
            pz += d * r22 + a * r20
            r01, r02 = ca * r01 + sa * r02, ca * r02 - sa * r01
            r11, r12 = ca * r11 + sa * r12, ca * r12 - sa * r11
            r21, r22 = ca * r21 + sa * r22, ca * r22 - sa * r21
        out.append((r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz))
    return out


def _apply_tool(cc: _ChainConsts, f: tuple[float, ...]) -> tuple[float, ...]:
    if cc.tool_is_identity:
        return f
    r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz = f
    (t00, t01, t02), (t10, t11, t12), (t20, t21, t22) = cc.R_tool
    tx, ty, tz = cc.p_tool
    return (
        r00 * t00 + r01 * t10 + r02 * t20,
        r00 * t01 + r01 * t11 + r02 * t21,
        r00 * t02 + r01 * t12 + r02 * t22,
        r10 * t00 + r11 * t10 + r12 * t20,
        r10 * t01 + r11 * t11 + r12 * t21,
        r10 * t02 + r11 * t12 + r12 * t22,
        r20 * t00 + r21 * t10 + r22 * t20,
        r20 * t01 + r21 * t11 + r22 * t21,
        r20 * t02 + r21 * t12 + r22 * t22,
        px + r00 * tx + r01 * ty + r02 * tz,
        py + r10 * tx + r11 * ty + r12 * tz,
        pz + r20 * tx + r21 * ty + r22 * tz,
    )


def fk_tuple(chain: DHChain, q) -> tuple[float, ...]:
    """Fast FK of one configuration as a flat tuple ``(r00, …, r22, px, py, pz)``.

    For hot loops (IK verification, servo loops) that want floats, not a 4x4 array.
    ``q`` is a sequence of ``chain.dof`` floats (rad / m); no validation is done.
    """
    cc = _consts(chain)
    if _COMPILED:
        r0, r1, r2, _ = _pose_compiled(cc, q).tolist()  # Python floats for float code
        return (*r0[:3], *r1[:3], *r2[:3], r0[3], r1[3], r2[3])
    if not cc.links:
        return _apply_tool(cc, (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0))
    return _apply_tool(cc, _frames_floats(cc, q)[-1])


def _pose_compiled(cc: _ChainConsts, q) -> np.ndarray:
    T = np.empty((4, 4))
    q = np.ascontiguousarray(q, dtype=float)  # one signature: compiled once (at import)
    fk_compiled.tip_pose_and_jacobian(*cc.packed, q, T, _NO_J, False)
    return T


def _pose_and_jacobian_compiled(cc: _ChainConsts, q) -> tuple[np.ndarray, np.ndarray]:
    T = np.empty((4, 4))
    J = np.empty((6, len(cc.links)))
    q = np.ascontiguousarray(q, dtype=float)
    fk_compiled.tip_pose_and_jacobian(*cc.packed, q, T, J, True)
    return T, J


_NO_J = np.empty((6, 0))  # the kernel's Jacobian argument when only the pose is wanted


def _to_matrix(f: tuple[float, ...]) -> np.ndarray:
    return np.array(
        [
            [f[0], f[1], f[2], f[9]],
            [f[3], f[4], f[5], f[10]],
            [f[6], f[7], f[8], f[11]],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


# --- batches: elementwise columns -----------------------------------------------------------


def _is_zero(x) -> bool:
    return isinstance(x, float) and x == 0.0


def _combo(coeffs, xs):
    """``Σ c·x`` over float constants c and float/array terms x, skipping exact zeros.

    The folding matters: the chain starts at the identity and most DH ``a``/``d`` are 0.
    """
    acc = 0.0
    for c, x in zip(coeffs, xs, strict=True):
        if c == 0.0 or _is_zero(x):
            continue
        term = x if c == 1.0 else (-x if c == -1.0 else c * x)
        acc = term if _is_zero(acc) else acc + term
    return acc


def _rotz(ct, st, u: list, v: list) -> tuple[list, list]:
    """Columns (u, v) post-multiplied by RotZ(theta): (ct·u + st·v, ct·v − st·u)."""
    if isinstance(ct, float):  # constant angle (prismatic joint)
        return (
            [_combo((ct, st), (ui, vi)) for ui, vi in zip(u, v, strict=True)],
            [_combo((ct, -st), (vi, ui)) for ui, vi in zip(u, v, strict=True)],
        )
    nu, nv = [], []
    for ui, vi in zip(u, v, strict=True):
        if _is_zero(ui) and _is_zero(vi):
            nu.append(0.0)
            nv.append(0.0)
        elif _is_zero(vi):
            nu.append(ct * ui)
            nv.append(-(st * ui))
        elif _is_zero(ui):
            nu.append(st * vi)
            nv.append(ct * vi)
        else:
            nu.append(ct * ui + st * vi)
            nv.append(ct * vi - st * ui)
    return nu, nv


def _rotx(ca: float, sa: float, u: list, v: list) -> tuple[list, list]:
    """Columns (u, v) post-multiplied by a constant RotX(alpha)."""
    return (
        [_combo((ca, sa), (ui, vi)) for ui, vi in zip(u, v, strict=True)],
        [_combo((ca, -sa), (vi, ui)) for ui, vi in zip(u, v, strict=True)],
    )


def _axpy(p: list, s, c: list) -> list:
    """``p + s·c`` per component; ``s`` is a float constant or an array (prismatic d)."""
    if _is_zero(s):
        return p
    out = []
    for pi, ci in zip(p, c, strict=True):
        if _is_zero(ci):
            out.append(pi)
        else:
            t = s * ci
            out.append(t if _is_zero(pi) else pi + t)
    return out


def _fk_chunk(cc: _ChainConsts, Qt: np.ndarray, out: np.ndarray) -> None:
    """FK of ``Qt`` (shape (n, m): one row per joint) into ``out`` (shape (m, 4, 4))."""
    c0: list = [1.0, 0.0, 0.0]
    c1: list = [0.0, 1.0, 0.0]
    c2: list = [0.0, 0.0, 1.0]
    p: list = [0.0, 0.0, 0.0]
    for lk, qi in zip(cc.links, Qt, strict=True):
        if lk.revolute:
            th = qi + lk.theta0 if lk.theta0 != 0.0 else qi
            ct, st = np.cos(th), np.sin(th)
            d = lk.d0
        else:
            ct, st = math.cos(lk.theta0), math.sin(lk.theta0)
            d = qi + lk.d0 if lk.d0 != 0.0 else qi
        if cc.modified:  # RotX(alpha) TransX(a) RotZ(theta) TransZ(d)
            p = _axpy(p, lk.a, c0)
            c1, c2 = _rotx(lk.ca, lk.sa, c1, c2)
            c0, c1 = _rotz(ct, st, c0, c1)
            p = _axpy(p, d, c2)
        else:  # RotZ(theta) TransZ(d) TransX(a) RotX(alpha)
            c0, c1 = _rotz(ct, st, c0, c1)
            p = _axpy(_axpy(p, d, c2), lk.a, c0)
            c1, c2 = _rotx(lk.ca, lk.sa, c1, c2)
    cols = (c0, c1, c2)
    if not cc.tool_is_identity:
        R, t = cc.R_tool, cc.p_tool
        p = [_combo((1.0, *t), (p[i], c0[i], c1[i], c2[i])) for i in range(3)]
        cols = tuple(
            [_combo((R[0][j], R[1][j], R[2][j]), (c0[i], c1[i], c2[i])) for i in range(3)]
            for j in range(3)
        )
    for j, col in enumerate(cols):
        for i in range(3):
            out[:, i, j] = col[i]
    for i in range(3):
        out[:, i, 3] = p[i]
    out[:, 3, :3] = 0.0
    out[:, 3, 3] = 1.0


def _fk_batch(chain: DHChain, q: np.ndarray) -> np.ndarray:
    cc = _consts(chain)
    batch = q.shape[:-1]
    n_poses = math.prod(batch)
    Q = q.reshape(n_poses, chain.dof)
    out = np.empty((n_poses, 4, 4))
    for i0 in range(0, Q.shape[0], _CHUNK):
        i1 = min(i0 + _CHUNK, Q.shape[0])
        _fk_chunk(cc, np.ascontiguousarray(Q[i0:i1].T), out[i0:i1])
    return out.reshape(*batch, 4, 4)


# --- public API -----------------------------------------------------------------------------


def joint_frames(chain: DHChain, q: np.ndarray) -> np.ndarray:
    """Frames ``T_base_i`` for i = 0 (base) … n, shape ``(..., n + 1, 4, 4)`` (no tool)."""
    q = _check_q(chain, q)
    if q.ndim == 1:
        frames = np.empty((chain.dof + 1, 4, 4))
        frames[0] = np.eye(4)
        for i, f in enumerate(_frames_floats(_consts(chain), q.tolist())):
            frames[i + 1] = _to_matrix(f)
        return frames
    L = link_transforms(chain, q)
    frames = np.empty((*L.shape[:-3], chain.dof + 1, 4, 4))
    frames[..., 0, :, :] = np.eye(4)
    for i in range(chain.dof):
        frames[..., i + 1, :, :] = frames[..., i, :, :] @ L[..., i, :, :]
    return frames


def forward_kinematics(chain: DHChain, q: np.ndarray) -> np.ndarray:
    """``T_base_tip`` = links · tooltip offset, shape ``(..., 4, 4)``."""
    q = _check_q(chain, q)
    if q.ndim == 1:
        if _COMPILED:
            return _pose_compiled(_consts(chain), q)
        return _to_matrix(fk_tuple(chain, q.tolist()))
    return _fk_batch(chain, q)


def forward_kinematics_matmul(chain: DHChain, q: np.ndarray) -> np.ndarray:
    """The same as :func:`forward_kinematics` by plain 4x4 products (slow; a test oracle)."""
    L = link_transforms(chain, q)
    T = np.broadcast_to(np.eye(4), (*L.shape[:-3], 4, 4))
    for i in range(chain.dof):
        T = T @ L[..., i, :, :]
    return T @ chain.T_last_tip


def jacobian_spatial(chain: DHChain, q: np.ndarray) -> np.ndarray:
    """Geometric Jacobian in the base frame, shape ``(..., 6, n)``.

    Rows 0-2 map joint velocities to the linear velocity of the tool-tip point, rows 3-5
    to the angular velocity, both expressed in the base frame (m/s and rad/s per unit joint
    velocity). This is the Jacobian the dVRK's damped-least-squares IK uses (dvrk.md 1.8).
    """
    q = _check_q(chain, q)
    if q.ndim == 1:
        if _COMPILED:
            return _pose_and_jacobian_compiled(_consts(chain), q)[1]
        return np.array(_jacobian_spatial_floats(chain, q.tolist())[0])
    return _fk_and_jacobian_batch(chain, q)[1]


def forward_kinematics_and_jacobian(chain: DHChain, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(T_base_tip (4, 4), spatial Jacobian (6, n))`` of one configuration in one pass over
    the chain (the 1 kHz teleoperation path needs both: pose and twist of the same joints);
    for a batch ``q`` (..., n): ``(..., 4, 4)`` and ``(..., 6, n)``."""
    q = _check_q(chain, q)
    if q.ndim != 1:
        return _fk_and_jacobian_batch(chain, q)
    if _COMPILED:
        return _pose_and_jacobian_compiled(_consts(chain), q)
    J, tip = _jacobian_spatial_floats(chain, q.tolist())
    return _to_matrix(tip), np.array(J)


def _fk_and_jacobian_batch(chain: DHChain, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Batched :func:`forward_kinematics_and_jacobian`: ``(..., 4, 4)`` and ``(..., 6, n)``
    from one set of joint frames (what :func:`jacobian_spatial` computes, plus the pose)."""
    F = joint_frames(chain, q)
    T = F[..., -1, :, :] @ chain.T_last_tip
    p_tip = T[..., :3, 3]
    # Modified DH: joint i acts about z of frame i; standard DH: about z of frame i-1.
    axes_frames = F[..., 1:, :, :] if chain.convention == "modified" else F[..., :-1, :, :]
    z = axes_frames[..., :3, 2]  # (..., n, 3)
    o = axes_frames[..., :3, 3]
    rev = chain.revolute[:, None]
    lin = np.where(rev, np.cross(z, p_tip[..., None, :] - o), z)
    ang = np.where(rev, z, 0.0)
    J = np.concatenate([np.swapaxes(lin, -1, -2), np.swapaxes(ang, -1, -2)], axis=-2)
    return T, J


def _jacobian_spatial_floats(chain: DHChain, q) -> tuple[list[list[float]], tuple[float, ...]]:
    """Spatial Jacobian (6 row lists) and the tip pose tuple of one configuration, as floats."""
    cc = _consts(chain)
    frames = _frames_floats(cc, q)
    tip = _apply_tool(cc, frames[-1]) if frames else fk_tuple(chain, q)
    tx, ty, tz = tip[9], tip[10], tip[11]
    if cc.modified:
        axes = frames
    else:
        axes = [(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0), *frames][
            : len(frames)
        ]
    J: list[list[float]] = [[], [], [], [], [], []]
    for lk, f in zip(cc.links, axes, strict=True):
        zx, zy, zz = f[2], f[5], f[8]
        if lk.revolute:
            rx, ry, rz = tx - f[9], ty - f[10], tz - f[11]
            lin = (zy * rz - zz * ry, zz * rx - zx * rz, zx * ry - zy * rx)
            ang = (zx, zy, zz)
        else:
            lin = (zx, zy, zz)
            ang = (0.0, 0.0, 0.0)
        for r in range(3):
            J[r].append(lin[r])
            J[r + 3].append(ang[r])
    return J, tip


def jacobian_body(chain: DHChain, q: np.ndarray) -> np.ndarray:
    """The spatial Jacobian with both halves rotated into the tool-tip frame, ``(..., 6, n)``."""
    J = jacobian_spatial(chain, q)
    R = forward_kinematics(chain, q)[..., :3, :3]
    Rt = np.swapaxes(R, -1, -2)
    return np.concatenate([Rt @ J[..., :3, :], Rt @ J[..., 3:, :]], axis=-2)
