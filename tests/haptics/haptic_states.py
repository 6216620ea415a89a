"""A path and haptic states near it, for the fixture rows' tests."""

from __future__ import annotations

import numpy as np

from davinci_sim.geometry import so3
from davinci_sim.geometry.path import Polyline
from davinci_sim.haptics.field import HapticState

ARC = Polyline(
    np.stack([[0.03 * np.cos(a), 0.03 * np.sin(a), 0.002 * a] for a in np.linspace(0, 3, 40)])
)


def states(n: int, seed: int, spread: float = 2e-4):
    """n haptic states of a tip wandering near the arc (steps of ``spread`` m per axis),
    seen from a tilted camera."""
    rng = np.random.default_rng(seed)
    T_world_camera = np.eye(4)
    T_world_camera[:3, :3] = so3.rotation_from_vector([0.3, -0.2, 0.5])
    T_world_camera[:3, 3] = [0.01, -0.02, 0.1]
    p_world = np.array([0.03, 0.0, 0.0])
    for _ in range(n):
        p_world = p_world + rng.normal(0.0, spread, 3)
        T = np.eye(4)
        T[:3, 3] = T_world_camera[:3, :3].T @ (p_world - T_world_camera[:3, 3])
        yield HapticState.from_values(
            T_camera_tip=T, twist_camera_tip=np.zeros(6), T_world_camera=T_world_camera
        )
