"""Pieces the skill exercises share: file I/O of their fields, the start of a repetition,
angles between directions, and visual-only geoms for drawing them.

The exercises (:mod:`~davinci_sim.tasks.camera_targeting`,
:mod:`~davinci_sim.tasks.ring_walk`, :mod:`~davinci_sim.tasks.needle_targeting`) are kinds
of :class:`~davinci_sim.tasks.base.Task`; what is the same for several of them lives here
so that each kind's module says only what is its own.
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from davinci_sim.geometry.floats import np_cross
from davinci_sim.tasks.base import TaskError, check_keys, common_fields
from davinci_sim.tasks.scene import digit_strokes
from davinci_sim.tasks.state import Phase

#: The task-file keys every kind has (:func:`~davinci_sim.tasks.base.common_fields`).
COMMON_KEYS = ("name", "description", "frame", "teleop", "fixture", "conditions", "walls",
               "scoring")  # fmt: skip


# ---------------------------------------------------------------- file format
def fields_from_dict(data: dict[str, Any], own: tuple[str, ...], required: tuple[str, ...]):
    """The constructor arguments of a kind's file mapping: the common ones and the kind's
    ``own`` keys present (``required`` ones must be)."""
    check_keys(data, {*COMMON_KEYS, *own}, required=("name", *required))
    kw = common_fields(data)
    kw.update({k: data[k] for k in own if k in data})
    return kw


def points(task: str, name: str, value, *, min_items: int = 1) -> np.ndarray:
    """``value`` as a read-only (k, 3) array of finite numbers (k ≥ ``min_items``)."""
    a = np.array(value, dtype=float)
    if a.ndim == 1 and a.shape == (3,) and min_items <= 1:
        a = a.reshape(1, 3)
    if a.ndim != 2 or a.shape[1] != 3 or len(a) < min_items or not np.all(np.isfinite(a)):
        raise TaskError(f"task {task!r}: {name} must be at least {min_items} point(s) [x, y, z]")
    a.setflags(write=False)
    return a


def positive(task: str, name: str, value) -> float:
    """``value`` as a float > 0 (TaskError otherwise)."""
    if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
        raise TaskError(f"task {task!r}: {name} must be a number > 0, got {value!r}")
    return float(value)


# ---------------------------------------------------------------- state
def start_transitions(phase: np.ndarray, at_start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The common start of a repetition: IDLE → READY with the tip at the start, READY →
    RUNNING once it leaves, FINISHED → RESULTS. Returns ``(new phase, begin)``, ``begin``
    (n,) bool marking the trials whose repetition starts at this sample."""
    new = phase.copy()
    new[(phase == Phase.IDLE) & at_start] = Phase.READY
    begin = (phase == Phase.READY) & ~at_start
    new[begin] = Phase.RUNNING
    new[phase == Phase.FINISHED] = Phase.RESULTS
    return new, begin


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n,) angle between directions ``a`` and ``b`` (n, 3) (any lengths > 0), rad in
    [0, π]; atan2 of the cross and dot products, accurate near 0 and π."""
    cross = np.linalg.norm(np_cross(a, b), axis=-1)  # (np.cross's bits, cheaper)
    return np.arctan2(cross, np.einsum("...i,...i->...", a, b))


def unit_rows(v, task: str, name: str) -> np.ndarray:
    """Rows of ``v`` (k, 3) scaled to unit length (TaskError for a zero row)."""
    a = np.array(v, dtype=float).reshape(-1, 3)
    n = np.linalg.norm(a, axis=1)
    if not np.all(np.isfinite(a)) or np.any(n < 1e-9):
        raise TaskError(f"task {task!r}: {name} must be nonzero directions [x, y, z]")
    out = a / n[:, None]
    out.setflags(write=False)
    return out


# ---------------------------------------------------------------- drawing
class VisualBody:
    """A static body of visual-only geoms (contype = conaffinity = 0, no mass: the
    instruments pass through, the physics and the keyframes are unchanged)."""

    def __init__(self, parent, name: str, prefix: str) -> None:
        self.body = parent.add_body(name=f"{prefix}{name}")
        self.prefix = prefix

    def geom(self, name: str, **kw):
        g = self.body.add_geom(name=f"{self.prefix}{name}", **kw)
        g.contype = 0
        g.conaffinity = 0
        g.mass = 0.0
        return g

    def sphere(self, name: str, p, radius: float, rgba) -> None:
        self.geom(name, type=mujoco.mjtGeom.mjGEOM_SPHERE, pos=np.asarray(p, dtype=float),
                  size=[radius, 0, 0], rgba=list(rgba))  # fmt: skip

    def capsule(self, name: str, a, b, radius: float, rgba) -> None:
        self.geom(name, type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                  fromto=np.concatenate([np.asarray(a, float), np.asarray(b, float)]),
                  size=[radius, 0, 0], rgba=list(rgba))  # fmt: skip

    def polyline(self, name: str, vertices, radius: float, rgba) -> None:
        v = np.asarray(vertices, dtype=float)
        for i, (a, b) in enumerate(zip(v[:-1], v[1:], strict=True)):
            self.capsule(f"{name}{i}", a, b, radius, rgba)

    def ring(self, name: str, centre, axis, radius: float, thickness: float, rgba,
             segments: int = 16) -> None:  # fmt: skip
        """A ring (a torus of capsules) around ``centre`` in the plane normal to ``axis``."""
        n = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
        u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        w = np.cross(n, u)
        a = np.linspace(0.0, 2.0 * np.pi, segments + 1)
        pts = np.asarray(centre, float) + radius * (np.outer(np.cos(a), u) + np.outer(np.sin(a), w))
        self.polyline(name, pts, thickness, rgba)

    def number(self, name: str, k: int, origin, right, up, height: float, rgba) -> None:
        """The number ``k`` in seven-segment strokes, its bottom-left at ``origin``."""
        for j, (a, b) in enumerate(digit_strokes(str(k), height)):
            pa = origin + a[0] * right + a[1] * up
            pb = origin + b[0] * right + b[1] * up
            self.capsule(f"{name}{k}_{j}", pa, pb, 0.0003, rgba)


def viewer_axes(T_world_camera) -> tuple[np.ndarray, np.ndarray]:
    """(right, up) unit vectors of the image of the endoscope at ``T_world_camera`` (x of
    the camera points to the image's left), or of a viewer facing +y when None."""
    if T_world_camera is None:
        return np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    R = np.asarray(T_world_camera, dtype=float)[:3, :3]
    return -R[:, 0], R[:, 1]


def world_points(task, p_task, T_world_camera) -> np.ndarray:
    """Task-frame points (k, 3) in the world: a camera-frame task is placed where the
    endoscope at ``T_world_camera`` is (ValueError without it)."""
    p = np.asarray(p_task, dtype=float).reshape(-1, 3)
    if task.frame == "world":
        return p
    if T_world_camera is None:
        raise ValueError(f"task {task.name!r} is in the camera frame: give T_world_camera")
    T = np.asarray(T_world_camera, dtype=float)
    return p @ T[:3, :3].T + T[:3, 3]
