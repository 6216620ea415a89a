"""Pose helpers for the model tests."""

import mujoco
import numpy as np


def body_pose(data: mujoco.MjData, body_id: int) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = data.xmat[body_id].reshape(3, 3)
    T[:3, 3] = data.xpos[body_id]
    return T


def site_pose(data: mujoco.MjData, site_id: int) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = data.site_xmat[site_id].reshape(3, 3)
    T[:3, 3] = data.site_xpos[site_id]
    return T


def set_joints(model: mujoco.MjModel, data: mujoco.MjData, prefix: str, names, q) -> None:
    for name, value in zip(names, q, strict=True):
        data.qpos[model.jnt_qposadr[model.joint(f"{prefix}/{name}").id]] = value
