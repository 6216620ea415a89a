"""dVRK ROS messages from simulation values, and back (dvrk.md §2.2; pure functions).

Builders take the simulator's values (:mod:`davinci_sim.sim.types`) and return message dicts
in one dialect: ``JointState``, ``PoseStamped`` (``frame_id`` = the pose's reference frame),
``TransformStamped`` (child = its moving frame, for ``/tf``), ``TwistStamped``,
``WrenchStamped``, ``crtk_msgs/OperatingState``, ``Float64MultiArray`` (Jacobians). Readers
turn validated incoming messages into the arm API's arguments and raise
:class:`CommandError` when a value cannot be a command (a zero quaternion, wrong joint names).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from davinci_sim.bridge.rosbridge.dialect import Dialect
from davinci_sim.sim.types import CartesianPose, CartesianTwist, JointState, OperatingState


class CommandError(ValueError):
    """An incoming message that is well typed but cannot be turned into a command."""


# =========================================================================== rotations
def quaternion_from_matrix(R) -> tuple[float, float, float, float]:
    """``(x, y, z, w)`` of a rotation matrix, ``w >= 0`` (Shepperd's method)."""
    m00, m01, m02 = float(R[0][0]), float(R[0][1]), float(R[0][2])
    m10, m11, m12 = float(R[1][0]), float(R[1][1]), float(R[1][2])
    m20, m21, m22 = float(R[2][0]), float(R[2][1]), float(R[2][2])
    tr = m00 + m11 + m22
    if tr > 0.0:
        s = 2.0 * math.sqrt(tr + 1.0)
        w, x, y, z = 0.25 * s, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s
    elif m00 > m11 and m00 > m22:
        s = 2.0 * math.sqrt(max(1.0 + m00 - m11 - m22, 1e-300))
        w, x, y, z = (m21 - m12) / s, 0.25 * s, (m01 + m10) / s, (m02 + m20) / s
    elif m11 > m22:
        s = 2.0 * math.sqrt(max(1.0 + m11 - m00 - m22, 1e-300))
        w, x, y, z = (m02 - m20) / s, (m01 + m10) / s, 0.25 * s, (m12 + m21) / s
    else:
        s = 2.0 * math.sqrt(max(1.0 + m22 - m00 - m11, 1e-300))
        w, x, y, z = (m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, 0.25 * s
    if w < 0.0:
        x, y, z, w = -x, -y, -z, -w
    return x, y, z, w


def matrix_from_quaternion(x: float, y: float, z: float, w: float) -> np.ndarray:
    """Rotation matrix of a quaternion; it must have unit norm within 1 % (then normalised).

    Raises:
        CommandError: for a zero or clearly non-unit quaternion.
    """
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not abs(n - 1.0) <= 0.01:
        raise CommandError(
            f"orientation quaternion ({x}, {y}, {z}, {w}) has norm {n:.4g}; it must be a unit "
            "quaternion"
        )
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


# =========================================================================== builders
def _list(a) -> list:
    return [] if a is None else a.tolist()


def joint_state(d: Dialect, js: JointState, stamp: float, seq: int = 0) -> dict:
    return {
        "header": d.header(stamp, "", seq),
        "name": list(js.name),
        "position": _list(js.position),
        "velocity": _list(js.velocity),
        "effort": _list(js.effort),
    }


def pose(T) -> dict:
    x, y, z, w = quaternion_from_matrix(T)
    return {
        "position": {"x": float(T[0][3]), "y": float(T[1][3]), "z": float(T[2][3])},
        "orientation": {"x": x, "y": y, "z": z, "w": w},
    }


def pose_stamped(d: Dialect, cp: CartesianPose, stamp: float, seq: int = 0) -> dict:
    """``geometry_msgs/PoseStamped`` in the pose's reference frame (dvrk.md 2.1)."""
    return {"header": d.header(stamp, cp.reference_frame, seq), "pose": pose(cp.T)}


def transform_stamped(d: Dialect, cp: CartesianPose, stamp: float, seq: int = 0) -> dict:
    """``geometry_msgs/TransformStamped`` reference → moving frame, as ``/tf`` carries it."""
    p = pose(cp.T)
    return {
        "header": d.header(stamp, cp.reference_frame, seq),
        "child_frame_id": cp.moving_frame,
        "transform": {"translation": p["position"], "rotation": p["orientation"]},
    }


def _vec3(v) -> dict:
    return {"x": float(v[0]), "y": float(v[1]), "z": float(v[2])}


def twist_stamped(d: Dialect, tw: CartesianTwist, stamp: float, seq: int = 0) -> dict:
    v = tw.twist
    return {
        "header": d.header(stamp, tw.reference_frame, seq),
        "twist": {"linear": _vec3(v[:3]), "angular": _vec3(v[3:])},
    }


def local_twist(measured_cv: CartesianTwist, measured_cp: CartesianPose) -> CartesianTwist:
    """``local/measured_cv`` (body/tip frame) from ``measured_cv`` (reference orientation):
    both halves rotated by ``R_reference_tipᵀ`` (dvrk.md 2.2)."""
    R_t = np.asarray(measured_cp.T)[:3, :3].T
    v = measured_cv.twist
    body = np.concatenate([R_t @ v[:3], R_t @ v[3:]])
    return CartesianTwist(
        body, measured_cp.moving_frame, measured_cp.moving_frame, measured_cv.timestamp
    )


def wrench_stamped(d: Dialect, w: Sequence[float], frame: str, stamp: float, seq: int = 0):
    return {
        "header": d.header(stamp, frame, seq),
        "wrench": {"force": _vec3(w[:3]), "torque": _vec3(w[3:6])},
    }


def operating_state(d: Dialect, s: OperatingState, stamp: float, seq: int = 0) -> dict:
    return {
        "header": d.header(stamp, "", seq),
        "state": s.state,
        "is_homed": bool(s.is_homed),
        "is_busy": bool(s.is_busy),
    }


def float64_multiarray(M) -> dict:
    """A matrix as ``std_msgs/Float64MultiArray``, row major, with its two dimensions."""
    a = np.atleast_2d(np.asarray(M, dtype=float))
    rows, cols = a.shape
    return {
        "layout": {
            "dim": [
                {"label": "rows", "size": rows, "stride": rows * cols},
                {"label": "columns", "size": cols, "stride": cols},
            ],
            "data_offset": 0,
        },
        "data": a.ravel().tolist(),
    }


def joy(d: Dialect, buttons: Sequence[int], stamp: float, seq: int = 0) -> dict:
    """``sensor_msgs/Joy`` as the dVRK sends console events: ``buttons = [1]`` pressed,
    ``[0]`` released, ``[2]`` quick tap; no axes (dvrk.md 2.3)."""
    return {"header": d.header(stamp, "", seq), "axes": [], "buttons": [int(b) for b in buttons]}


# =========================================================================== readers
def pose_matrix(p: dict) -> np.ndarray:
    """4x4 transform of a validated ``geometry_msgs/Pose``."""
    o, q = p["position"], p["orientation"]
    T = np.eye(4)
    T[:3, :3] = matrix_from_quaternion(q["x"], q["y"], q["z"], q["w"])
    T[:3, 3] = (o["x"], o["y"], o["z"])
    return T


def wrench_vector(w: dict) -> list[float]:
    """Force then torque of a validated ``geometry_msgs/Wrench``."""
    f, t = w["force"], w["torque"]
    return [f["x"], f["y"], f["z"], t["x"], t["y"], t["z"]]


def twist_vector(tw: dict) -> list[float]:
    v, w = tw["linear"], tw["angular"]
    return [v["x"], v["y"], v["z"], w["x"], w["y"], w["z"]]


def ordered(values: list[float], names: list[str], joint_names: Sequence[str], what: str):
    """``values`` in the arm's joint order when the message names its joints.

    A JointState without names is taken in the arm's order (as the dVRK does). With names,
    they must be the arm's joints, in any order.

    Raises:
        CommandError: for unknown or repeated names, or names and values of different lengths.
    """
    if not names:
        return values
    if len(names) != len(values):
        raise CommandError(f"{what}: {len(names)} names for {len(values)} values")
    if sorted(names) != sorted(joint_names):
        raise CommandError(
            f"{what}: joint names {names} do not match the arm's joints {list(joint_names)}"
        )
    index = {n: i for i, n in enumerate(names)}
    return [values[index[n]] for n in joint_names]
