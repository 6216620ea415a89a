"""Forward kinematics and Jacobians of :class:`~davinci_sim.kinematics.chain.DHChain`.

Every function accepts one configuration (shape ``(n,)``) or a batch (shape ``(..., n)``)
and returns arrays with the same leading batch shape. Poses are 4x4 homogeneous transforms
``T_base_frame`` in m; the base is the chain's first frame (the RCM for PSM/ECM, dvrk.md
section 1.2).

One law, one kernel: :func:`~davinci_sim.kinematics.fk_compiled.tip_poses` (numba-compiled
scalar float arithmetic, row by row; plain Python when compiling is off or fails: the same
operations, the same bits). One configuration is a batch of one (the live arms, every tick),
a batch is n rows (the study's trials); a row's bits do not depend on the batch.
:func:`forward_kinematics_matmul` (4x4 products of :func:`link_transforms`) is the slow,
independent oracle the tests compare with.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np

from davinci_sim.kinematics import fk_compiled
from davinci_sim.kinematics.chain import DHChain
from davinci_sim.kinematics.jit import kernel_array


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


# --- the kernel ----------------------------------------------------------------------------


def _run(
    chain: DHChain, q, jacobian: bool, frames: bool = False
) -> tuple[tuple[int, ...], np.ndarray, np.ndarray, np.ndarray]:
    """The kernel on joints ``q`` (..., n) (checked): (batch shape, T (m, 4, 4), J (m, 6, n
    or 0), frames (m or 1, n, 12))."""
    q = np.asarray(q, dtype=float)
    cc = _consts(chain)
    n = len(cc.links)
    if q.ndim == 0 or q.shape[-1] != n:
        _check_q(chain, q)  # raises
    batch = q.shape[:-1]
    m = math.prod(batch) if batch else 1
    Q = kernel_array(q).reshape(m, n)
    T = np.empty((m, 4, 4))
    J = np.empty((m, 6, n if jacobian else 0))
    F = np.empty((m if frames else 1, n, 12))
    fk_compiled.tip_poses(*cc.packed, Q, T, J, jacobian, F)
    return batch, T, J, F


def fk_tuple(chain: DHChain, q) -> tuple[float, ...]:
    """FK of one configuration as a flat tuple ``(r00, …, r22, px, py, pz)``.

    For hot loops (IK verification, servo loops) that want floats, not a 4x4 array.
    ``q`` is a sequence of ``chain.dof`` floats (rad / m).
    """
    r0, r1, r2, _ = _run(chain, q, False)[1][0].tolist()
    return (*r0[:3], *r1[:3], *r2[:3], r0[3], r1[3], r2[3])


# --- public API -----------------------------------------------------------------------------


def joint_frames(chain: DHChain, q: np.ndarray) -> np.ndarray:
    """Frames ``T_base_i`` for i = 0 (base) … n, shape ``(..., n + 1, 4, 4)`` (no tool)."""
    batch, _, _, F = _run(chain, q, False, frames=True)
    m, n = F.shape[0], chain.dof
    frames = np.zeros((m, n + 1, 4, 4))
    frames[:, 0] = np.eye(4)
    frames[:, 1:, :3, :3] = F[:, :, :9].reshape(m, n, 3, 3)
    frames[:, 1:, :3, 3] = F[:, :, 9:]
    frames[:, 1:, 3, 3] = 1.0
    return frames.reshape(*batch, n + 1, 4, 4)


def forward_kinematics(chain: DHChain, q: np.ndarray) -> np.ndarray:
    """``T_base_tip`` = links · tooltip offset, shape ``(..., 4, 4)``."""
    batch, T, _, _ = _run(chain, q, False)
    return T.reshape(*batch, 4, 4) if batch else T[0]


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
    return forward_kinematics_and_jacobian(chain, q)[1]


def forward_kinematics_and_jacobian(chain: DHChain, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(T_base_tip (4, 4), spatial Jacobian (6, n))`` of one configuration in one pass over
    the chain (the 1 kHz teleoperation path needs both: pose and twist of the same joints);
    for a batch ``q`` (..., n): ``(..., 4, 4)`` and ``(..., 6, n)``."""
    batch, T, J, _ = _run(chain, q, True)
    if not batch:
        return T[0], J[0]
    return T.reshape(*batch, 4, 4), J.reshape(*batch, 6, chain.dof)


def jacobian_body(chain: DHChain, q: np.ndarray) -> np.ndarray:
    """The spatial Jacobian with both halves rotated into the tool-tip frame, ``(..., 6, n)``."""
    R, J = forward_kinematics_and_jacobian(chain, q)
    Rt = np.swapaxes(R[..., :3, :3], -1, -2)
    return np.concatenate([Rt @ J[..., :3, :], Rt @ J[..., 3:, :]], axis=-2)
