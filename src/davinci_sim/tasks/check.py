"""Is a task doable where it is? :func:`check_task`, per point: reachable, and in view.

Before a study spends minutes on trials (or a session starts), the task's points
(:attr:`~davinci_sim.tasks.base.Task.check_points`, by default its ``view_points``: a path's
numbered points; a peg board's pegs) are checked on the task's own scene at its start
keyframe: the task's PSM (or one of its instruments) must reach each point with the tool's
orientation at that keyframe (the dVRK's IK: within joint limits, dvrk.md 1.2 and 1.8, the
45 mm insertion rule), and the left endoscope camera must see it (in front of the camera,
inside the image). ``davinci-sim task check FILE`` prints the table; ``study`` and
``serve --task`` refuse a task that fails it before any work.

Three optional declarations of a kind widen the check: ``view_directions`` ((k, 3), one per
view point, nan rows for none) — the tool must reach that point *pointing that way* (its
tip frame's z; the orientation nearest the keyframe's that does); ``view_turns`` ((k, 3),
rotation vectors in the task's frame, rad, nan rows for none) — the tool must reach that
point with its keyframe orientation turned by that much (a carried object's wrist turns,
:mod:`davinci_sim.tasks.carry`); ``camera_targets``
((k, 3), with ``depth``, m) — points the operator must centre in the endoscope's view
from ``depth``: the ECM must reach the camera pose on the line from its RCM through the
point (its shaft passes through the RCM), and at that pose the point must show at the
image's centre (checked by the ECM's forward kinematics); those rows follow the view
points, numbered on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from davinci_sim.geometry.so3 import rotation_from_vector
from davinci_sim.kinematics.ik import inverse_kinematics
from davinci_sim.model.cameras import project_left
from davinci_sim.model.config import SceneConfig
from davinci_sim.tasks.base import Task


@dataclass(frozen=True)
class PointCheck:
    """One point of a task, checked."""

    index: int
    """1-based, as the task numbers its points."""
    p_task: tuple[float, float, float]
    """The point in the task's frame, m."""
    reachable: bool
    why: str
    """Why it is not reachable ("" when it is)."""
    pixel: tuple[float, float] | None
    """Where the left endoscope image shows it (None: behind the camera)."""
    in_view: bool
    turned_deg: float | None = None
    """The tool's turn from its keyframe orientation it was checked with (``view_turns``),
    deg; None: the keyframe's orientation (or ``view_directions``')."""

    @property
    def ok(self) -> bool:
        return self.reachable and self.in_view


def check_task(task: Task) -> list[PointCheck]:
    """Check every point of ``task`` (see the module docstring); for a kind done with
    several instruments (``task.instruments``: peg transfer's PSM1 and PSM2, each working
    its side of the board) a point is reachable when one of them reaches it."""
    from davinci_sim.sim.simulation import Simulation

    psms = tuple(getattr(task, "instruments", None) or (task.teleop.psm,))
    scene = SceneConfig(arms=(*psms, "ECM"), include_console=False, include_patient=False)
    sim = Simulation(scene, keyframe=task.teleop.keyframe)
    try:
        camera = scene.endoscope
        T_task_camera = task.T_task_camera(sim.T_cart_camera())
        T_camera_task = np.linalg.inv(T_task_camera)
        # The tools' orientations at the keyframe, and their joints as the IK's seeds.
        start = {n: (sim.arms[n].setpoint_cp().T.copy(), sim.arms[n].setpoint_jp()) for n in psms}
        out = []
        points = np.asarray(task.check_points, dtype=float).reshape(-1, 3)
        directions = getattr(task, "view_directions", None)
        turns = getattr(task, "view_turns", None)
        for k, p in enumerate(points, start=1):
            p_camera = (T_camera_task @ np.append(p, 1.0))[:3]
            d = None if directions is None else np.asarray(directions[k - 1], dtype=float)
            turn = None if turns is None else np.asarray(turns[k - 1], dtype=float)
            why, reached = [], False
            for n in psms:
                R_keyframe, seed = start[n][0][:3, :3], start[n][1]
                goal = start[n][0].copy()
                goal[:3, 3] = p_camera
                if d is not None and np.all(np.isfinite(d)):
                    goal[:3, :3] = _pointing(R_keyframe, T_camera_task[:3, :3] @ d)
                if turn is not None and np.all(np.isfinite(turn)):
                    # The turn is in the task's frame, the keyframe's orientation in the camera's.
                    R_camera_task = T_camera_task[:3, :3]
                    goal[:3, :3] = (
                        R_camera_task @ rotation_from_vector(turn) @ R_camera_task.T @ R_keyframe
                    )
                # The kinematics' IK, not the arm's command: a point one instrument
                # cannot reach is no error to log when another does.
                arm = sim.arms[n]
                result = inverse_kinematics(arm.kin, np.linalg.inv(arm.base_frame()[0]) @ goal,
                                            seed)  # fmt: skip
                reached |= bool(result.success)
                if not result.success:
                    why.append(f"{n}: inverse_kinematics: {result.message}")
            pixel = project_left(p_camera, camera)
            in_view = pixel is not None and (
                0 <= pixel[0] < camera.width and 0 <= pixel[1] < camera.height
            )
            shown = None if pixel is None else (float(pixel[0]), float(pixel[1]))
            p_task = (float(p[0]), float(p[1]), float(p[2]))
            why = [] if reached else why
            turned = (None if turn is None or not np.all(np.isfinite(turn))
                      else math.degrees(float(np.linalg.norm(turn))))  # fmt: skip
            out.append(PointCheck(k, p_task, reached, "; ".join(why), shown, bool(in_view),
                                  turned))  # fmt: skip
        targets = getattr(task, "camera_targets", None)
        if targets is not None:
            first = len(out) + 1
            for k, p in enumerate(np.asarray(targets, dtype=float), start=first):
                out.append(_camera_check(sim, task, k, p, T_camera_task, camera))
        return out
    finally:
        sim.close()


def _pointing(R_keyframe: np.ndarray, d: np.ndarray) -> np.ndarray:
    """The rotation nearest ``R_keyframe`` whose z axis is ``d`` (the shortest turn)."""
    a, b = R_keyframe[:, 2], d / np.linalg.norm(d)
    axis, c = np.cross(a, b), float(a @ b)
    s = float(np.linalg.norm(axis))
    if s < 1e-12:  # parallel (no turn) or opposite (half a turn about the frame's x)
        return R_keyframe if c > 0 else R_keyframe @ np.diag([1.0, -1.0, -1.0])
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]]) / s
    turn = np.eye(3) + s * K + (1.0 - c) * (K @ K)  # Rodrigues: angle atan2(s, c) about axis
    return turn @ R_keyframe


def _camera_check(sim, task: Task, k: int, p_task, T_camera_task, camera) -> PointCheck:
    """Can the ECM centre ``p_task`` at ``task.depth``? (see the module docstring)"""
    ecm = sim.arms["ECM"]
    T_cart_task = sim.T_cart_camera() @ T_camera_task
    p_cart = (T_cart_task @ np.append(p_task, 1.0))[:3]
    rcm = ecm.base_frame()[0][:3, 3]
    axis = (p_cart - rcm) / np.linalg.norm(p_cart - rcm)
    goal = ecm.measured_cp().T.copy()
    goal[:3, 3] = p_cart - float(task.depth) * axis
    q, result = ecm.inverse_kinematics(ecm.setpoint_jp(), goal)
    shown, centred = None, False
    if q is not None:
        pose, _ = ecm.forward_kinematics(q)
        T_cart_camera = pose.T
        p_camera = np.linalg.solve(T_cart_camera, np.append(p_cart, 1.0))[:3]
        pixel = project_left(p_camera, camera)
        if pixel is not None:
            shown = (float(pixel[0]), float(pixel[1]))
            off = np.degrees(np.arctan2(np.hypot(p_camera[0], p_camera[1]), p_camera[2]))
            centred = bool(off <= task.centre_tolerance
                           and abs(p_camera[2] - task.depth) <= task.depth_tolerance)  # fmt: skip
    why = "" if q is not None else f"the ECM cannot centre it: {result.message}"
    p = tuple(float(x) for x in p_task)
    return PointCheck(k, p, q is not None, why, shown, centred)


def task_problem(task: Task) -> str | None:
    """One line saying which points of ``task`` fail :func:`check_task`, or None."""
    bad = [c for c in check_task(task) if not c.ok]
    if not bad:
        return None
    parts = []
    for c in bad:
        what = [] if c.reachable else [f"unreachable ({c.why})"]
        what += [] if c.in_view else ["out of the endoscope's view"]
        parts.append(f"point {c.index} {' and '.join(what)}")
    return f"task {task.name!r}: " + "; ".join(parts)
