"""Rigid transforms: elementary rotations, 4x4 transforms and their inverse, aiming frames.

Transforms are 4x4 homogeneous matrices named ``T_<reference>_<frame>`` (the pose of
``frame`` expressed in ``reference``), lengths in m, angles in rad.
"""

from __future__ import annotations

import numpy as np


def rot_x(angle: float) -> np.ndarray:
    """Rotation matrix about x by ``angle`` rad."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> np.ndarray:
    """Rotation matrix about y by ``angle`` rad."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float) -> np.ndarray:
    """Rotation matrix about z by ``angle`` rad."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def transform(R=None, p=None) -> np.ndarray:
    """A 4x4 transform from a rotation (default identity) and a translation (default 0)."""
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if p is not None:
        T[:3, 3] = p
    return T


def invert_transform(T: np.ndarray) -> np.ndarray:
    """Inverse of a rigid 4x4 transform (Rᵀ, −Rᵀp), or of each of a stack (..., 4, 4)."""
    T = np.asarray(T, dtype=float)
    if T.ndim == 2:
        out = np.eye(4)
        R = T[:3, :3]
        out[:3, :3] = R.T
        out[:3, 3] = -R.T @ T[:3, 3]
        return out
    out = np.zeros_like(T)
    R_t = np.swapaxes(T[..., :3, :3], -1, -2)
    out[..., :3, :3] = R_t
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", R_t, T[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def look_at_rotation(position, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Rotation of a MuJoCo camera at ``position`` looking at ``target``.

    MuJoCo cameras look along their −z axis with +y up in the image.
    """
    forward = np.asarray(target, dtype=float) - np.asarray(position, dtype=float)
    forward /= np.linalg.norm(forward)
    up = np.asarray(up, dtype=float)
    if abs(np.dot(forward, up)) > 0.999:  # looking straight up/down: any other up will do
        up = np.array([0.0, 1.0, 0.0])
    x = np.cross(forward, up)
    x /= np.linalg.norm(x)
    y = np.cross(x, forward)
    return np.column_stack([x, y, -forward])


def segment_rotation(direction) -> np.ndarray:
    """A rotation whose z axis is ``direction`` (for cylinders/boxes along a segment)."""
    z = np.asarray(direction, dtype=float)
    z = z / np.linalg.norm(z)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])
