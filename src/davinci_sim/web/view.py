"""What the page shows, from one snapshot: :func:`console_view` (pure, JSON-ready).

The heads-up display of the surgeon's view needs, besides the images, where each tool tip is
in the left endoscope image and where the guidance force points there. The PSMs'
``measured_cp`` is in the camera frame (the ECM tip, dvrk.md 1.6: x to the image's left, y up,
z into the scene; :func:`davinci_sim.model.cameras.T_tip_camera`); the left camera sits half
a baseline towards +x (:func:`davinci_sim.model.cameras.project_left` projects into it). The haptic
loop's requested wrench is in HRSV, whose axes the teleoperation aligns with the camera
frame's (dvrk.md 4.2), so the arrow is drawn from the tip along that force.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from davinci_sim.model.cameras import CameraConfig, project_left

#: Length of the drawn force arrow per newton, m (5 N, the seed's largest G_max: 2 cm).
ARROW_M_PER_N = 0.004


def path_guide(p_camera, T_world_camera, path, camera: CameraConfig) -> dict:
    """The depth cue of a path task for a 2-D screen: the path's closest point to the tool
    tip ``p_camera`` (camera frame, m) in the left image (``pixel``), and how much deeper
    than the tip it lies along the camera's axis (``depth_mm``: > 0 the path is further
    away, push in; < 0 pull back). ``path`` is in the world frame, ``T_world_camera`` the
    camera's pose there (4x4)."""
    T = np.asarray(T_world_camera, dtype=float)
    p_world = T[:3, :3] @ np.asarray(p_camera, dtype=float) + T[:3, 3]
    c_world = np.asarray(path.closest_point(p_world[None]).point, dtype=float).reshape(3)
    c_camera = T[:3, :3].T @ (c_world - T[:3, 3])
    pixel = project_left(c_camera, camera)
    return {
        "pixel": None if pixel is None else list(pixel),
        "depth_mm": 1000.0 * float(c_camera[2] - float(np.asarray(p_camera)[2])),
        "distance_mm": 1000.0 * float(np.linalg.norm(c_camera - np.asarray(p_camera))),
    }


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _vector(v) -> list[float]:
    return [float(x) for x in np.asarray(v, dtype=float).ravel()]


def console_view(snap, camera: CameraConfig, task=None) -> dict[str, Any]:
    """The page's state from a :class:`~davinci_sim.sim.handle.Snapshot`: time, arms, the
    console, teleoperations, hands, haptics, the task, and the tool tips with their force
    arrows in the left image (pixels); with a world-frame path ``task``, its tool tip's
    :func:`path_guide` (``guide``)."""
    extras = snap.extras or {}
    arms = {
        name: {"state": a.operating_state.state, "homed": bool(a.operating_state.is_homed)}
        for name, a in snap.arms.items()
    }
    console = extras.get("console")
    teleops = {}
    for name, s in extras.items():
        if hasattr(s, "following") and hasattr(s, "psm"):
            teleops[name] = {
                "mtm": s.mtm,
                "psm": s.psm,
                "state": s.current_state,
                "following": bool(s.following),
                "clutched": bool(s.clutched),
                "selected": bool(s.selected),
                "scale": float(s.scale),
                "p_mtm_hrsv": None
                if s.T_hrsv_mtm is None
                else _vector(np.asarray(s.T_hrsv_mtm)[:3, 3]),
            }
    haptics = extras.get("haptics")
    requested = {} if haptics is None else dict(haptics.requested)
    tips = {}
    for t in teleops.values():
        psm = snap.arms.get(t["psm"])
        if psm is None:
            continue
        p = np.asarray(psm.measured_cp.position, dtype=float)
        force = np.asarray(requested.get(t["mtm"], np.zeros(6)), dtype=float)[:3]
        tip = project_left(p, camera)
        head = project_left(p + ARROW_M_PER_N * force, camera)
        tips[t["psm"]] = {
            "mtm": t["mtm"],
            "p_camera": _vector(p),
            "pixel": None if tip is None else list(tip),
            "force": _vector(force),
            "force_pixel": None if head is None else list(head),
        }
    ecm = snap.arms.get("ECM")
    path = getattr(task, "path", None)
    if path is not None and task.frame == "world" and ecm is not None:
        tip = tips.get(task.teleop.psm)
        if tip is not None:  # the ECM's measured_cp is the camera in the cart (dvrk.md 1.6)
            tip["guide"] = path_guide(tip["p_camera"], ecm.measured_cp.T, path, camera)
    hands = {n.split("/")[0]: dict(s) for n, s in extras.items() if n.endswith("/hand")}
    synthetic = extras.get("synthetic")
    sources = {}
    for name, s in extras.items():
        if name.endswith("/device") and hasattr(s, "kind"):
            mtm = name.split("/")[0]
            sources[mtm] = _source(s.kind, mtm in hands, bool(synthetic and synthetic["running"]))
    task = extras.get("task")
    guidance_B = getattr(task, "guidance_B", None)  # (an adaptive condition's B now)
    view = {
        "time": float(snap.time),
        "tick": int(snap.tick),
        "arms": arms,
        "teleops": teleops,
        "tips": tips,
        "hands": hands,
        "console": None
        if console is None
        else {
            "teleop_enabled": bool(console.teleop_enabled),
            "scale": float(console.scale),
            "buttons": {k: bool(v) for k, v in console.buttons.items()},
        },
        "task": None
        if task is None
        else {
            "name": task.task,
            "condition": task.condition,
            "phase": task.phase,
            "repetition": int(task.repetition),
            "completed": int(task.completed),
            "distance": _finite(task.distance_to_path),
            "progress": getattr(task, "progress", ""),
            "guidance_B": None if guidance_B is None else _finite(guidance_B),
        },
        "synthetic": _synthetic(synthetic),
        "sources": sources,
    }
    return view


#: What drives an MTM, by its device's kind (the page says it next to each arm).
_SOURCES = {"network": "ROS client mode", "udp": "UDP stream", "simulated": "simulated hand"}


def _source(kind: str, page_hand: bool, synthetic: bool) -> str:
    if kind == "simulated" and synthetic:
        return "synthetic trainee"
    if kind == "simulated" and page_hand:
        return "keys/gamepad"
    return _SOURCES.get(kind, kind)


def _synthetic(state) -> dict | None:
    if state is None:
        return None
    return {k: (v if isinstance(v, (bool, int, str)) or v is None else float(v))
            for k, v in dict(state).items()}  # fmt: skip
