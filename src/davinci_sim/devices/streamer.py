"""The sawSocketStreamer JSON format (dvrk.md 5), as pure encode/decode functions.

One UDP datagram is one compact JSON object whose keys are command or event names and
whose values are cisst objects serialised with their member names:

* ``prmPositionCartesianGet`` (``measured_cp``): ``{"Position": {"Rotation": 3x3 nested list,
  "Translation": [x, y, z]}, "ReferenceFrame", "MovingFrame", "Timestamp", "Valid", ...}``;
* ``prmStateJoint`` (``measured_js``, ``gripper/measured_js``): ``{"Name": [...],
  "Position": [...], "Velocity": [...], "Effort": [...], "Timestamp", "Valid", ...}``;
* ``prmVelocityCartesianGet`` (``measured_cv``): ``{"Velocity": [vx, vy, vz, wx, wy, wz]}``
  (cisst HEAD) or ``{"VelocityLinear": [...], "VelocityAngular": [...]}`` (older cisst);
* ``prmEventButton`` (pedal/button events): ``{"Type": "PRESSED" | "RELEASED" |
  "CLICKED"}``. How cisst renders this enum in JSON is not verified (dvrk.md 7), so the
  names are required here (integers would be ambiguous: the cisst enum numbers PRESSED 0,
  RELEASED 1, while the Joy convention has pressed 1, released 0); a Joy-style
  ``{"buttons": [1]}`` is accepted too;
* ``prmForceCartesianSet`` (``body/servo_cf``, ``spatial/servo_cf``): ``{"Force": [fx, fy,
  fz, tx, ty, tz], "Mask": [...6 bools], "MovingFrame": ...}``.

Objects with ``"Valid": false`` are ignored, as the dVRK marks data it cannot vouch for.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping

import numpy as np

from davinci_sim.devices.buttons import ButtonEvent, parse_button_event
from davinci_sim.sim.validation import as_transform, short_repr

#: Datagram names the UDP device understands as a master's state (dvrk.md 5, streamerMTML).
POSE = "measured_cp"
TWIST = "measured_cv"
GRIPPER = "gripper/measured_js"
#: Names that are valid streamer output of an MTM but not needed here.
IGNORED = frozenset({"measured_js", "setpoint_js", "setpoint_cp", "operating_state"})
#: Button/pedal event names (dvrk.md 2.3: console events and raw pedals).
BUTTONS = frozenset(
    {"clutch", "camera", "coag", "bicoag", "cam_minus", "cam_plus", "operator_present", "head"}
)


class StreamerFormatError(ValueError):
    """A datagram or object that does not follow the socket-streamer format."""


def parse_datagram(data: bytes) -> dict:
    """The JSON object of one datagram.

    Raises:
        StreamerFormatError: if it is not UTF-8 JSON or not an object.
    """
    try:
        obj = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise StreamerFormatError(f"datagram is not JSON: {e}") from None
    if not isinstance(obj, dict):
        raise StreamerFormatError(f"datagram must be a JSON object, got {type(obj).__name__}")
    return obj


def is_valid(payload: Mapping) -> bool:
    """False when the object says ``"Valid": false``."""
    return payload.get("Valid", True) is not False


def _numbers(value, n: int, what: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):  # OverflowError: an integer of 400 digits
        raise StreamerFormatError(
            f"{what} must be {n} finite numbers, got {short_repr(value)}"
        ) from None
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise StreamerFormatError(f"{what} must be {n} finite numbers, got {short_repr(value)}")
    return arr


def decode_pose(payload) -> np.ndarray:
    """4x4 pose of a ``prmPositionCartesianGet`` object (m)."""
    if not isinstance(payload, Mapping) or not isinstance(payload.get("Position"), Mapping):
        raise StreamerFormatError(f"{POSE} needs a 'Position' object, got {payload!r}")
    pos = payload["Position"]
    T = np.eye(4)
    try:
        T[:3, :3] = np.asarray(pos["Rotation"], dtype=float)
    except (KeyError, TypeError, ValueError):
        raise StreamerFormatError(f"Position.Rotation must be a 3x3 list, got {pos!r}") from None
    T[:3, 3] = _numbers(pos.get("Translation"), 3, "Position.Translation")
    T, msg = as_transform(T, "Position")
    if T is None:
        raise StreamerFormatError(msg)
    return T


def decode_twist(payload) -> np.ndarray:
    """Twist (6,) of a ``prmVelocityCartesianGet`` object (m/s, rad/s)."""
    if not isinstance(payload, Mapping):
        raise StreamerFormatError(f"{TWIST} must be an object, got {payload!r}")
    if "Velocity" in payload:
        return _numbers(payload["Velocity"], 6, "Velocity")
    if "VelocityLinear" in payload and "VelocityAngular" in payload:
        return np.concatenate(
            [
                _numbers(payload["VelocityLinear"], 3, "VelocityLinear"),
                _numbers(payload["VelocityAngular"], 3, "VelocityAngular"),
            ]
        )
    raise StreamerFormatError(f"{TWIST} needs 'Velocity' (or VelocityLinear/Angular): {payload!r}")


def decode_joint_position(payload) -> np.ndarray:
    """``Position`` of a ``prmStateJoint`` object."""
    if not isinstance(payload, Mapping) or "Position" not in payload:
        raise StreamerFormatError(f"joint state needs a 'Position' list, got {payload!r}")
    try:
        arr = np.asarray(payload["Position"], dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise StreamerFormatError(
            f"Position must be numbers, got {payload['Position']!r}"
        ) from None
    if arr.size == 0 or not np.all(np.isfinite(arr)):
        raise StreamerFormatError(f"Position must be finite numbers, got {payload['Position']!r}")
    return arr


def decode_button(payload) -> ButtonEvent:
    """The event of a ``prmEventButton`` object (or a Joy-style ``{"buttons": [...]}``)."""
    if isinstance(payload, Mapping) and "Type" in payload:
        kind = payload["Type"]
        if not isinstance(kind, str):
            raise StreamerFormatError(
                f"button Type must be 'PRESSED', 'RELEASED' or 'CLICKED', got {kind!r}"
            )
        try:
            return parse_button_event(kind)
        except ValueError as e:
            raise StreamerFormatError(str(e)) from None
    try:
        return parse_button_event(payload)
    except ValueError as e:
        raise StreamerFormatError(str(e)) from None


def encode_pose(
    T,
    reference_frame: str = "HRSV",
    moving_frame: str = "",
    timestamp: float = 0.0,
    *,
    automatic_timestamp: bool = False,
) -> dict:
    """A ``prmPositionCartesianGet`` object for ``T`` (4x4, m)."""
    T = np.asarray(T, dtype=float)
    return {
        "Position": {"Rotation": T[:3, :3].tolist(), "Translation": T[:3, 3].tolist()},
        "ReferenceFrame": reference_frame,
        "MovingFrame": moving_frame,
        "Timestamp": float(timestamp),
        "AutomaticTimestamp": automatic_timestamp,
        "Valid": True,
    }


def _floats(a) -> list[float] | None:
    return None if a is None else [float(x) for x in np.atleast_1d(a)]


def encode_joint_state(
    names,
    position,
    timestamp: float = 0.0,
    *,
    velocity=None,
    effort=None,
    automatic_timestamp: bool = False,
) -> dict:
    """A ``prmStateJoint`` object (velocity and effort ``null`` unless given)."""
    return {
        "Name": list(names),
        "Position": _floats(position),
        "Velocity": _floats(velocity),
        "Effort": _floats(effort),
        "Timestamp": float(timestamp),
        "AutomaticTimestamp": automatic_timestamp,
        "Valid": True,
    }


def encode_twist(twist) -> dict:
    """A ``prmVelocityCartesianGet`` object (cisst HEAD member ``Velocity``)."""
    return {"Velocity": [float(x) for x in twist], "Valid": True}


def encode_wrench(wrench, moving_frame: str = "") -> dict:
    """A ``prmForceCartesianSet`` object: force (N) then torque (N·m)."""
    w = [float(x) for x in wrench]
    if len(w) != 6 or not all(map(math.isfinite, w)):
        raise StreamerFormatError(f"wrench must be 6 finite numbers, got {wrench!r}")
    return {"Force": w, "Mask": [True] * 6, "MovingFrame": moving_frame}


def datagram(**objects) -> bytes:
    """One compact JSON datagram; keys with a ``/`` are passed as ``{"a/b": ...}`` via
    ``datagram(**{"gripper/measured_js": ...})``."""
    return json.dumps(objects, separators=(",", ":")).encode("utf-8")
