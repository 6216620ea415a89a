"""Conversion of rigid transforms to MjSpec element poses (the math is in ``geometry``).

All transforms are 4x4 homogeneous matrices named ``T_<reference>_<frame>`` (the pose of
``frame`` expressed in ``reference``). MuJoCo quaternions are ``(w, x, y, z)``.
"""

from __future__ import annotations

import mujoco
import numpy as np


def mat_to_quat(R: np.ndarray) -> np.ndarray:
    """MuJoCo ``(w, x, y, z)`` quaternion of a rotation matrix.

    The matrix is re-orthonormalised first: some dVRK frames are given with 9 digits
    (e.g. cos 30° = 0.866025404), and a quaternion can only hold a proper rotation.
    """
    u, _, vt = np.linalg.svd(np.asarray(R, dtype=float))
    R_ortho = u @ vt
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, R_ortho.reshape(9))
    return q


def set_pose(element, T: np.ndarray) -> None:
    """Set ``element.pos``/``element.quat`` (body, geom, site, camera, …) from ``T``."""
    element.pos = np.asarray(T[:3, 3], dtype=float)
    element.quat = mat_to_quat(T[:3, :3])
