"""Is a task doable where it is? :func:`check_task`, per point: reachable, and in view.

Before a study spends minutes on trials (or a session starts), the task's points
(:attr:`~davinci_sim.tasks.base.Task.check_points`, by default its ``view_points``: a path's
numbered points; a peg board's pegs) are checked on the task's own scene at its start
keyframe: the task's PSM (or one of its instruments) must reach each point with the tool's
orientation at that keyframe (the dVRK's IK: within joint limits, dvrk.md 1.2 and 1.8, the
45 mm insertion rule), and the left endoscope camera must see it (in front of the camera,
inside the image). ``davinci-sim task check FILE`` prints the table; ``study`` and
``serve --task`` refuse a task that fails it before any work.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

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
        for k, p in enumerate(points, start=1):
            p_camera = (T_camera_task @ np.append(p, 1.0))[:3]
            why, reached = [], False
            for n in psms:
                goal, seed = start[n]
                goal[:3, 3] = p_camera
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
            out.append(PointCheck(k, p_task, reached, "; ".join(why), shown, bool(in_view)))
        return out
    finally:
        sim.close()


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
