"""The message schemas of a recording: Foxglove's well-known ones and the simulator's own,
all JSON Schema (``jsonschema`` encoding) for JSON messages (``json`` encoding).

Foxglove's panels recognise a channel by its schema's *name*: ``foxglove.FrameTransforms``
(the 3-D panel's frames), ``foxglove.PoseInFrame``, ``foxglove.CompressedImage`` (the image
panel: ``data`` base64 in JSON), ``foxglove.Log`` (the log panel). The simulator's own
schemas (``davinci_sim.*``) are plain JSON objects that the plot, raw-message and state
panels read as they are: joint states, wrenches, the task's state and results, events, the
recorded calls (``sim/inputs.py``) and the joint positions of the whole model.

Times: ``timestamp`` is ``{"sec", "nsec"}`` of the simulation's time (s since the session's
start; Foxglove shows it as 1970-01-01 plus that time); a message's log time in the file is
the same time in ns. Units: m, rad, N, N·m, s.
"""

from __future__ import annotations

import json
import math

_TIME = {
    "type": "object",
    "title": "time",
    "properties": {"sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer"}},
}
_VEC3 = {
    "type": "object",
    "properties": {k: {"type": "number"} for k in ("x", "y", "z")},
}
_QUAT = {
    "type": "object",
    "properties": {k: {"type": "number"} for k in ("x", "y", "z", "w")},
}
_NUMBERS = {"type": "array", "items": {"type": ["number", "null"]}}


def _object(title: str, description: str, properties: dict) -> dict:
    return {
        "title": title,
        "description": description,
        "$comment": "Written by davinci-sim (records/mcap_schemas.py)",
        "type": "object",
        "properties": properties,
    }


_FRAME_TRANSFORM = {
    "type": "object",
    "properties": {
        "timestamp": _TIME,
        "parent_frame_id": {"type": "string"},
        "child_frame_id": {"type": "string"},
        "translation": _VEC3,
        "rotation": _QUAT,
    },
}

#: Schema name -> JSON Schema.
SCHEMAS: dict[str, dict] = {
    "foxglove.FrameTransforms": _object(
        "foxglove.FrameTransforms",
        "Transforms between frames (child frame's pose in the parent frame), m and unit quaternion",
        {"transforms": {"type": "array", "items": _FRAME_TRANSFORM}},
    ),
    "foxglove.PoseInFrame": _object(
        "foxglove.PoseInFrame",
        "A pose in a frame, m and unit quaternion",
        {
            "timestamp": _TIME,
            "frame_id": {"type": "string"},
            "pose": {
                "type": "object",
                "properties": {"position": _VEC3, "orientation": _QUAT},
            },
        },
    ),
    "foxglove.CompressedImage": _object(
        "foxglove.CompressedImage",
        "A compressed image (data: base64 of the JPEG or PNG bytes)",
        {
            "timestamp": _TIME,
            "frame_id": {"type": "string"},
            "data": {"type": "string", "contentEncoding": "base64"},
            "format": {"type": "string"},
        },
    ),
    "foxglove.Log": _object(
        "foxglove.Log",
        "A log message (level: 1 debug, 2 info, 3 warning, 4 error, 5 fatal)",
        {
            "timestamp": _TIME,
            "level": {"type": "integer"},
            "message": {"type": "string"},
            "name": {"type": "string"},
            "file": {"type": "string"},
            "line": {"type": "integer"},
        },
    ),
    "davinci_sim.JointState": _object(
        "davinci_sim.JointState",
        "An arm's joint state as the dVRK's measured_js/setpoint_js (rad or m, rad/s or m/s, "
        "N·m or N)",
        {
            "timestamp": _TIME,
            "tick": {"type": "integer"},
            "name": {"type": "array", "items": {"type": "string"}},
            "position": _NUMBERS,
            "velocity": _NUMBERS,
            "effort": _NUMBERS,
        },
    ),
    "davinci_sim.Wrench": _object(
        "davinci_sim.Wrench",
        "A wrench: force (N) and torque (N·m) in frame_id",
        {"timestamp": _TIME, "frame_id": {"type": "string"}, "force": _VEC3, "torque": _VEC3},
    ),
    "davinci_sim.Qpos": _object(
        "davinci_sim.Qpos",
        "The whole model's joint positions (MuJoCo qpos, m and rad; free bodies' quaternions)",
        {"timestamp": _TIME, "tick": {"type": "integer"}, "qpos": _NUMBERS},
    ),
    "davinci_sim.Call": _object(
        "davinci_sim.Call",
        "A call the simulation's handle ran right before tick `tick` (target.method(*args, "
        "**kwargs)); args and kwargs in davinci_sim's exact JSON (records/jsonvalue.py)",
        {
            "timestamp": _TIME,
            "seq": {"type": "integer"},
            "tick": {"type": "integer"},
            "target": {"type": "string"},
            "method": {"type": "string"},
            "args": {"type": "array"},
            "kwargs": {"type": "object"},
        },
    ),
    "davinci_sim.Event": _object(
        "davinci_sim.Event",
        "An event of an arm or a component (console buttons, teleoperation states, task "
        "phases and results): source, event name and its payload",
        {
            "timestamp": _TIME,
            "source": {"type": "string"},
            "event": {"type": "string"},
            "payload": {},
        },
    ),
    "davinci_sim.State": _object(
        "davinci_sim.State",
        "A component's published state (the console, a teleoperation, the haptic loop, the "
        "task session: phase, repetition, distance to the path in m)",
        {"timestamp": _TIME, "tick": {"type": "integer"}, "state": {"type": "object"}},
    ),
    "davinci_sim.Step": _object(
        "davinci_sim.Step",
        "One step of an episode (an environment's rollout, a study trial): observation, "
        "action, reward, terminated, truncated, info; arrays as lists",
        {
            "timestamp": _TIME,
            "episode": {"type": "integer"},
            "step": {"type": "integer"},
            "observation": {},
            "action": {},
            "reward": {"type": ["number", "null"]},
            "terminated": {"type": "boolean"},
            "truncated": {"type": "boolean"},
            "info": {"type": "object"},
        },
    ),
}


def schema_bytes(name: str) -> bytes:
    """The JSON Schema of ``name`` as the file stores it."""
    return json.dumps(SCHEMAS[name], separators=(",", ":")).encode()


def stamp(t: float) -> dict:
    """``{"sec", "nsec"}`` of a time ``t`` >= 0 in s."""
    ns = time_ns(t)
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def time_ns(t: float) -> int:
    """A time in s as integer ns (>= 0; not finite: 0)."""
    return max(0, round(t * 1e9)) if math.isfinite(t) else 0


def pose_fields(T) -> tuple[dict, dict]:
    """The position and orientation (unit quaternion x, y, z, w) of a 4x4 pose ``T``."""
    import mujoco
    import numpy as np

    q = np.empty(4)  # (MuJoCo's C conversion: ~1 µs; the recorder converts ~10 per snapshot)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(T[:3, :3], dtype=float).reshape(9))
    w, x, y, z = q
    p = T[:3, 3]
    return (
        {"x": float(p[0]), "y": float(p[1]), "z": float(p[2])},
        {"x": float(x), "y": float(y), "z": float(z), "w": float(w)},
    )


def numbers(values) -> list:
    """Floats as a JSON list (non-finite: null)."""
    return [float(v) if math.isfinite(v) else None for v in map(float, values)]
