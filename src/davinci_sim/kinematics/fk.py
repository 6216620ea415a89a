"""Forward kinematics and Jacobians of :class:`~davinci_sim.kinematics.chain.DHChain`.

Every function accepts one configuration (shape ``(n,)``) or a batch (shape ``(..., n)``)
and returns arrays with the same leading batch shape. Poses are 4x4 homogeneous transforms
``T_base_frame`` in m; the base is the chain's first frame (the RCM for PSM/ECM, dvrk.md
section 1.2).
"""

from __future__ import annotations

import numpy as np

from davinci_sim.kinematics.chain import DHChain


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
        raise ValueError(f"{chain.name}: expected joint array with last dimension {chain.dof}, got {q.shape}")
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


def joint_frames(chain: DHChain, q: np.ndarray) -> np.ndarray:
    """Frames ``T_base_i`` for i = 0 (base) … n, shape ``(..., n + 1, 4, 4)`` (no tool)."""
    L = link_transforms(chain, q)
    frames = np.empty((*L.shape[:-3], chain.dof + 1, 4, 4))
    frames[..., 0, :, :] = np.eye(4)
    for i in range(chain.dof):
        frames[..., i + 1, :, :] = frames[..., i, :, :] @ L[..., i, :, :]
    return frames


def forward_kinematics(chain: DHChain, q: np.ndarray) -> np.ndarray:
    """``T_base_tip`` = links · tooltip offset, shape ``(..., 4, 4)``."""
    L = link_transforms(chain, q)
    if chain.dof == 0:
        return np.broadcast_to(chain.T_last_tip, (*L.shape[:-3], 4, 4)).copy()
    T = L[..., 0, :, :]
    for i in range(1, chain.dof):
        T = T @ L[..., i, :, :]
    return T @ chain.T_last_tip


def jacobian_spatial(chain: DHChain, q: np.ndarray) -> np.ndarray:
    """Geometric Jacobian in the base frame, shape ``(..., 6, n)``.

    Rows 0-2 map joint velocities to the linear velocity of the tool-tip point, rows 3-5
    to the angular velocity, both expressed in the base frame (m/s and rad/s per unit joint
    velocity). This is the Jacobian the dVRK's damped-least-squares IK uses (dvrk.md 1.8).
    """
    F = joint_frames(chain, q)
    p_tip = (F[..., -1, :, :] @ chain.T_last_tip)[..., :3, 3]
    # Modified DH: joint i acts about z of frame i; standard DH: about z of frame i-1.
    axes_frames = F[..., 1:, :, :] if chain.convention == "modified" else F[..., :-1, :, :]
    z = axes_frames[..., :3, 2]  # (..., n, 3)
    o = axes_frames[..., :3, 3]
    rev = chain.revolute[:, None]
    lin = np.where(rev, np.cross(z, p_tip[..., None, :] - o), z)
    ang = np.where(rev, z, 0.0)
    return np.concatenate([np.swapaxes(lin, -1, -2), np.swapaxes(ang, -1, -2)], axis=-2)


def jacobian_body(chain: DHChain, q: np.ndarray) -> np.ndarray:
    """The spatial Jacobian with both halves rotated into the tool-tip frame, ``(..., 6, n)``."""
    J = jacobian_spatial(chain, q)
    R = forward_kinematics(chain, q)[..., :3, :3]
    Rt = np.swapaxes(R, -1, -2)
    return np.concatenate([Rt @ J[..., :3, :], Rt @ J[..., 3:, :]], axis=-2)
