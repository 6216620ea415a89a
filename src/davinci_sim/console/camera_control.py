"""Camera control with both hands (ECM teleoperation): pure geometry.

While the camera pedal is held, the surgeon moves the endoscope with both MTMs. The camera
follows the midpoint ``c`` of the two handles as seen from the eyes (the HRSV origin): its
left/right angle in the HRSV x-z plane turns the ECM yaw, its up/down angle in the y-z
plane the pitch, the change of its distance from the eyes (times the scale) the insertion,
and the turn of the hands' "up" vector about the viewing axis the roll. This is the
behaviour of the dVRK's ``mtsTeleOperationECM`` (read for this issue; dvrk.md documents only
its topics and scale, 4.3); the code here is our own formulation. A spring keeps the hands'
relative placement so they move as if holding one image.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from davinci_sim.geometry.floats import np_cross


def _norm(v: np.ndarray) -> float:
    """``np.linalg.norm`` of a 1-D float vector as numpy computes it (the square root of
    ``v.dot(v)``: the same bits), without its dispatch."""
    return math.sqrt(float(v.dot(v)))


def _unit(v: np.ndarray) -> np.ndarray:
    n = _norm(v)
    if n < 1e-12:
        raise ValueError(f"cannot normalise a zero vector {v!r}")
    return v / n


@dataclass(frozen=True, eq=False)
class HandsGeometry:
    """Where the two handles are, in HRSV (m)."""

    center: np.ndarray
    """Midpoint of the handles, "the centre of the image"."""
    up: np.ndarray
    """Unit vector ``(p_right − p_left) × c``: the image's up direction."""
    side: np.ndarray
    """Unit vector ``c × up``: from the left hand towards the right one."""
    half_width: float
    """Half the hands' separation along ``side``."""
    half_depth: float
    """Half the hands' separation along the viewing direction ``c/|c|``."""


def hands_geometry(p_hrsv_left: np.ndarray, p_hrsv_right: np.ndarray) -> HandsGeometry:
    """The geometry of the two handle positions (HRSV, m).

    Raises:
        ValueError: when the hands coincide or are aligned with the eyes (no "up").
    """
    left = np.asarray(p_hrsv_left, dtype=float)
    right = np.asarray(p_hrsv_right, dtype=float)
    lr = right - left
    c = 0.5 * (left + right)
    up = _unit(np_cross(lr, c))
    side = _unit(np_cross(c, up))
    return HandsGeometry(c, up, side, 0.5 * float(side @ lr), 0.5 * float(_unit(c) @ lr))


def signed_angle(a: np.ndarray, b: np.ndarray, axis: np.ndarray) -> float:
    """Angle (rad) from ``a`` to ``b`` about ``axis`` (right hand), in ]−π, π]."""
    return math.atan2(float(np_cross(a, b) @ axis), float(a @ b))


_X, _Y, _Z = np.eye(3)


def camera_motion(
    initial: HandsGeometry, current: HandsGeometry, scale: float
) -> tuple[float, float, float, float]:
    """``(d_yaw, d_pitch, d_insertion, d_roll)`` of the camera for the hands' motion
    (rad, rad, m, rad), before the roll compensation of :func:`ecm_joint_goal`."""
    c0, c = initial.center, current.center
    d_yaw = -signed_angle(_unit(c0 * (1, 0, 1)), _unit(c * (1, 0, 1)), _Y)
    d_pitch = signed_angle(_unit(c0 * (0, 1, 1)), _unit(c * (0, 1, 1)), _X)
    d_insertion = scale * (_norm(c0) - _norm(c))
    d_roll = -signed_angle(_unit(initial.up * (1, 1, 0)), _unit(current.up * (1, 1, 0)), _Z)
    return d_yaw, d_pitch, d_insertion, d_roll


def ecm_joint_goal(
    q_ecm0: np.ndarray,
    motion: tuple[float, float, float, float],
    camera_roll_offset: float = 0.0,
) -> np.ndarray:
    """ECM joints (yaw, pitch, insertion, roll) for ``motion`` from ``q_ecm0``.

    Image left/right and up/down are turned into yaw and pitch through the camera's roll
    (the initial roll plus the new one and the scope's offset), so that they stay image
    directions whatever the roll.
    """
    d_yaw, d_pitch, d_ins, d_roll = motion
    r = d_roll + float(q_ecm0[3]) + camera_roll_offset
    cr, sr = math.cos(r), math.sin(r)
    q = np.array(q_ecm0, dtype=float)
    q[0] += d_yaw * cr - d_pitch * sr
    q[1] += d_pitch * cr + d_yaw * sr
    q[2] += d_ins
    q[3] += d_roll
    return q


def hands_goals(initial: HandsGeometry, current: HandsGeometry) -> tuple[np.ndarray, np.ndarray]:
    """Where each hand should be to keep its initial placement relative to the other
    (left, right), given the current midpoint and orientation of the pair."""
    c = current.center
    offset = initial.half_width * current.side + initial.half_depth * _unit(c)
    return c - offset, c + offset


def hands_force(
    goal: np.ndarray,
    position: np.ndarray,
    velocity: np.ndarray,
    stiffness: float,
    friction: np.ndarray,
    ratio: float = 1.0,
) -> np.ndarray:
    """Force (3,) on one hand: spring to its goal minus viscous friction, times ``ratio``."""
    return ratio * (stiffness * (goal - position) - np.asarray(friction) * velocity)
