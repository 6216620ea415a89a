"""Drawing a path-following task in the MuJoCo scene: a thin tube and numbered markers.

:func:`add_path_visual` adds to a ``mujoco.MjSpec`` (e.g. from
:func:`davinci_sim.model.build_spec`) one static body, ``<prefix>path``, holding capsules
along the path, a sphere at each numbered point, and the point's number as a seven-segment
digit drawn with thin capsules beside it. Every geom is visual only (contype = conaffinity =
0, no mass), so the instruments pass through the drawing and the physics is unchanged; the
spec's keyframes stay valid (no degrees of freedom are added).

The digits are drawn in a plane facing a viewer: the endoscope, if its pose
``T_world_camera`` is given (e.g. :meth:`Simulation.T_cart_camera` at the ``surgical``
keyframe), else a vertical plane facing −y of the world. A task in the ``camera`` frame is
drawn where the path is at that camera pose: the drawing does not follow a moving
endoscope.
"""

from __future__ import annotations

import mujoco
import numpy as np

from davinci_sim.tasks.task import PathTask

# Seven-segment layout: segments as pairs of corners of a (0..1) x (0..2) box.
_CORNERS = {
    "TL": (0, 2),
    "TR": (1, 2),
    "ML": (0, 1),
    "MR": (1, 1),
    "BL": (0, 0),
    "BR": (1, 0),
}
_SEGMENTS = {
    "a": ("TL", "TR"),
    "b": ("TR", "MR"),
    "c": ("MR", "BR"),
    "d": ("BL", "BR"),
    "e": ("ML", "BL"),
    "f": ("TL", "ML"),
    "g": ("ML", "MR"),
}
_DIGITS = {
    "0": "abcdef",
    "1": "bc",
    "2": "abged",
    "3": "abgcd",
    "4": "fgbc",
    "5": "afgcd",
    "6": "afgedc",
    "7": "abc",
    "8": "abcdefg",
    "9": "abcdfg",
}


def digit_strokes(text: str, height: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Strokes (start, end) of ``text`` (digits) in a 2-D plane: x right, y up, m; the
    first digit's bottom-left corner at the origin, digits ``height`` tall."""
    half = height / 2
    strokes = []
    for k, ch in enumerate(text):
        if ch not in _DIGITS:
            raise ValueError(f"only digits can be drawn, got {text!r}")
        x0 = k * 0.9 * height
        for seg in _DIGITS[ch]:
            a, b = (np.array(_CORNERS[c], dtype=float) * half for c in _SEGMENTS[seg])
            strokes.append((a + [x0, 0.0], b + [x0, 0.0]))
    return strokes


def add_path_visual(
    spec: mujoco.MjSpec,
    task: PathTask,
    *,
    T_world_task: np.ndarray | None = None,
    T_world_camera: np.ndarray | None = None,
    prefix: str = "task/",
    digit_height: float = 0.006,
) -> mujoco.MjsBody:
    """Add ``task``'s path, markers and numbers to ``spec`` (see the module docstring).

    Args:
        spec: the scene's spec (modified in place).
        task: the task; its ``visual`` section sets radii and colours.
        T_world_task: pose of the task's frame in the world; default: identity for a
            ``world`` task, ``T_world_camera`` for a ``camera`` task.
        T_world_camera: the endoscope's pose, to face the numbers to it (and to place a
            ``camera``-frame task).
        prefix: name prefix of the body and geoms.
        digit_height: height of the numbers, m.

    Returns:
        The added body.

    Raises:
        ValueError: a ``camera``-frame task without ``T_world_task`` or ``T_world_camera``.
    """
    if T_world_task is None:
        if task.frame == "world":
            T_world_task = np.eye(4)
        elif T_world_camera is not None:
            T_world_task = np.asarray(T_world_camera, dtype=float)
        else:
            raise ValueError(
                f"task {task.name!r} is in the camera frame: give T_world_camera (or "
                "T_world_task) to place it in the scene"
            )
    T = np.asarray(T_world_task, dtype=float)
    path = task.path.transformed(T)
    markers = task.markers @ T[:3, :3].T + T[:3, 3]
    vis = task.visual
    body = spec.worldbody.add_body(name=f"{prefix}path")

    def geom(name: str, **kw):
        g = body.add_geom(name=f"{prefix}{name}", **kw)
        g.contype = 0
        g.conaffinity = 0
        g.mass = 0.0
        return g

    capsule = mujoco.mjtGeom.mjGEOM_CAPSULE
    for i, (a, b) in enumerate(zip(path.vertices[:-1], path.vertices[1:], strict=True)):
        geom(
            f"tube{i}",
            type=capsule,
            fromto=np.concatenate([a, b]),
            size=[vis.tube_radius, 0, 0],
            rgba=list(vis.path_rgba),
        )
    if T_world_camera is not None:
        Rc = np.asarray(T_world_camera, dtype=float)[:3, :3]
        right, up = -Rc[:, 0], Rc[:, 1]  # camera x points to the image's left
    else:
        right, up = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    for n, m in enumerate(markers, start=1):
        geom(
            f"marker{n}",
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            pos=m,
            size=[vis.marker_radius, 0, 0],
            rgba=list(vis.marker_rgba),
        )
        origin = m + (vis.marker_radius + 0.0015) * (right + up) / np.sqrt(2)
        for k, (a, b) in enumerate(digit_strokes(str(n), digit_height)):
            pa = origin + a[0] * right + a[1] * up
            pb = origin + b[0] * right + b[1] * up
            geom(
                f"label{n}_{k}",
                type=capsule,
                fromto=np.concatenate([pa, pb]),
                size=[0.0003, 0, 0],
                rgba=list(vis.marker_rgba),
            )
    return body
