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
import re
from collections.abc import Mapping
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


def task_marks(task, T_world_camera, camera: CameraConfig, progress: str = "", objects=(),
               object_frame=()) -> dict | None:  # fmt: skip
    """What the heads-up display marks of an exercise, in the camera frame (m) and the left
    image (pixels): its numbered ``targets`` (with each one's required tool ``direction``,
    unit, camera frame, when the task has ``directions``), the ``current`` one (0-based,
    from the task's progress text "… target k of K"; None when it names none), and a path
    task's ``wire`` (its path every 2 mm; the seed's path has its own depth cue,
    :func:`path_guide`), a peg board's ``pegs`` (their tops; ``target``: a peg to put a
    ring on) and ``rings`` (``objects``: their centres in the task's frame, m), a needle
    exercise's ``needle`` (its ``start`` pose's swage, top and point, its plane's
    ``normal``, its ``centre`` now, from ``objects``, and with ``object_frame`` (its frame
    now, 4×4, task frame) where it is ``now``: its ``ends``, swage, top and point, and its
    ``normal``), a suture pad's ``sutures`` (each pair's entry and exit marks) and the
    ``current_pair`` (0-based, from the progress text
    "… mark k …"; None when it names none). None for a task in the camera frame or with
    nothing to mark."""
    if task is None or getattr(task, "frame", "world") != "world":
        return None
    T = np.asarray(T_world_camera, dtype=float)
    R, t = T[:3, :3], T[:3, 3]

    def to_camera(p_world) -> np.ndarray:
        return (np.asarray(p_world, dtype=float).reshape(-1, 3) - t) @ R

    out: dict[str, Any] = {}
    targets = getattr(task, "targets", None)
    if targets is not None:
        directions = getattr(task, "directions", None)
        marks = []
        for k, p in enumerate(to_camera(targets)):
            pixel = project_left(p, camera)
            mark = {"label": str(k + 1), "p_camera": _vector(p),
                    "pixel": None if pixel is None else list(pixel)}  # fmt: skip
            if directions is not None:
                d = R.T @ np.asarray(directions[k], dtype=float)
                d /= np.linalg.norm(d)
                mark["direction"] = _vector(d)
                # Where the shaft of a tool pointing that way is, 12 mm back from the target.
                tail = project_left(p - 0.012 * d, camera)
                mark["shaft_pixel"] = None if tail is None else list(tail)
            marks.append(mark)
        out["targets"] = marks
        found = re.search(r"target (\d+) of (\d+)", progress or "")
        out["current"] = None if found is None else int(found.group(1)) - 1
    path = getattr(task, "path", None)
    if path is not None and task.kind != "path":
        s = np.linspace(0.0, path.length, max(2, int(path.length / 0.002) + 1))
        p_camera = to_camera(np.array([path.point_at(x) for x in s]))
        pixels = [project_left(p, camera) for p in p_camera]
        out["wire"] = {
            "p_camera": [_vector(p) for p in p_camera],
            "pixels": [None if q is None else list(q) for q in pixels],
        }
    pegs = getattr(task, "pegs", None)
    if pegs is not None:
        targets = set(int(i) for i in task.target_pegs)
        tops = [[x, y, task.board_top + task.peg_height] for x, y in np.asarray(pegs)]
        out["pegs"] = [_mark(str(i + 1), p, camera, target=i in targets)
                       for i, p in enumerate(to_camera(tops))]  # fmt: skip
    if len(objects) and pegs is not None:
        out["rings"] = [_mark(str(i + 1), p, camera) for i, p in enumerate(to_camera(objects))]
    T_start = getattr(task, "T_world_start", None)
    needle = getattr(task, "needle", None)
    if T_start is not None and needle is not None:  # (not drawn: the needle is in the view)

        def ends(T_world_needle) -> list[dict]:  # (its swage, the middle of its arc, point)
            p = T_world_needle[:3, :3] @ needle.points(np.array([0.0, 0.5, 1.0])).T
            return [_mark(k, q, camera) for k, q in zip(("swage", "top", "point"),
                                                        to_camera((p + T_world_needle[:3, 3:4]).T),
                                                        strict=True)]  # fmt: skip

        out["needle"] = {
            "start": ends(T_start),
            "normal": _vector(R.T @ T_start[:3, 2]),
            "centre": _mark("centre", to_camera(objects)[0], camera) if len(objects) else None,
        }  # fmt: skip
        if len(object_frame):  # (what a person sees of it: its ends and the way it faces)
            T_now = np.asarray(object_frame, dtype=float).reshape(4, 4)
            out["needle"]["now"] = {"ends": ends(T_now), "normal": _vector(R.T @ T_now[:3, 2])}
    pad = getattr(task, "pad", None)
    if pad is not None:  # (the marks are drawn on the skin: these ring the pair to pass)
        pairs = to_camera(pad.marks_world().reshape(-1, 3)).reshape(-1, 2, 3)
        out["sutures"] = [{"label": str(k + 1), "entry": _mark(f"in {k + 1}", e, camera),
                           "exit": _mark(f"out {k + 1}", x, camera)}
                          for k, (e, x) in enumerate(pairs)]  # fmt: skip
        found = re.search(r"mark (\d+)", progress or "")
        out["current_pair"] = None if found is None else int(found.group(1)) - 1
    return out or None


def _mark(label: str, p_camera, camera: CameraConfig, **extra) -> dict:
    pixel = project_left(p_camera, camera)
    return {"label": label, "p_camera": _vector(p_camera),
            "pixel": None if pixel is None else list(pixel), **extra}  # fmt: skip


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
            # The tool's direction (the tip frame's z, where the jaws point), camera frame.
            "z_camera": _vector(np.asarray(psm.measured_cp.T, dtype=float)[:3, 2]),
            # ... and the way its jaws open (the tip frame's y), camera frame.
            "y_camera": _vector(np.asarray(psm.measured_cp.T, dtype=float)[:3, 1]),
            "jaw": _finite(float(psm.jaw_measured_js.position[0]))
            if getattr(psm, "jaw_measured_js", None) is not None
            else None,
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
    session = extras.get("task")
    marks = None
    if ecm is not None:
        marks = task_marks(task, ecm.measured_cp.T, camera, getattr(session, "progress", ""),
                           getattr(session, "objects", ()),
                           getattr(session, "object_frame", ()))  # fmt: skip
    hands = {n.split("/")[0]: dict(s) for n, s in extras.items() if n.endswith("/hand")}
    synthetic = extras.get("synthetic")
    sources = {}
    for name, s in extras.items():
        if name.endswith("/device") and hasattr(s, "kind"):
            mtm = name.split("/")[0]
            sources[mtm] = _source(s.kind, mtm in hands, bool(synthetic and synthetic["running"]))
    # (what the page calls the session's distance: None for a kind where it means nothing
    # to the trainee, e.g. a needle's distance from where it started)
    label = getattr(task, "DISTANCE_LABEL", "deviation")
    task = session
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
            "distance": None if label is None else _finite(task.distance_to_path),
            "distance_label": label,
            "progress": getattr(task, "progress", ""),
            "guidance_B": None if guidance_B is None else _finite(guidance_B),
            "marks": marks,
            "last": _last_attempt(task.last),
        },
        "synthetic": _synthetic(synthetic),
        "sources": sources,
    }
    return view


#: A teleoperation still aligning whose last warning is at most this old (s of simulated
#: time) and not its first in this state is shown as stuck: the teleoperation warns every
#: 2 s while it cannot start (``TeleopPSMConfig.warning_interval``), and the first warning
#: of an ordinary start (the MTM turning to the tool's orientation takes 2-3 s) is no
#: problem.
ALIGN_WARNING_AGE = 2.5


def problems(view: dict, messages: Mapping[str, tuple[str, str, float, int]]) -> list[dict]:
    """What stops the operator and needs an action, from the page's state ``view``
    (:func:`console_view`) and each source's last error or warning (``messages``: name ->
    (level, text, sim time s, how many in a row), as the arms and teleoperations send
    them).

    One entry per problem, ``{"source", "kind", "reason"}``: an arm in FAULT (``fault``, the
    reason its last error); a selected teleoperation stopped while the console's
    teleoperation is on and the operator present (``stopped``, e.g. its PSM faulted); a
    teleoperation that still cannot align its MTM (``aligning``, its warning). The page
    shows them with one remedy, the ``recover`` op."""
    out = []
    for name, arm in view["arms"].items():
        if arm["state"] == "FAULT":
            level, text, _, _ = messages.get(name, ("", "", 0.0, 0))
            reason = text if level == "error" else f"{name} is in FAULT"
            out.append({"source": name, "kind": "fault", "reason": reason})
    console = view.get("console") or {}
    on = console.get("teleop_enabled") and (console.get("buttons") or {}).get("operator_present")
    now = view["time"]
    for name, t in view["teleops"].items():
        level, text, at, repeats = messages.get(name, ("", "", -math.inf, 0))
        if on and t["selected"] and t["state"] == "DISABLED" and level == "error":
            out.append({"source": name, "kind": "stopped", "reason": text})
        elif (t["state"] == "ALIGNING_MTM" and level == "warning" and repeats >= 2
              and now - at <= ALIGN_WARNING_AGE):  # fmt: skip
            out.append({"source": name, "kind": "aligning", "reason": text})
    return out


def _last_attempt(row: dict) -> dict | None:
    """The last finished attempt's score, verdict and metrics (JSON numbers; None before
    the first)."""
    if not row:
        return None
    out = {}
    for k, v in row.items():
        if isinstance(v, (bool, int, str)) or v is None:
            out[k] = v
        elif isinstance(v, (float, np.floating, np.integer)):
            out[k] = _finite(float(v))
    return out


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
