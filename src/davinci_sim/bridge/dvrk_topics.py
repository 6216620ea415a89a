"""The dVRK CRTK topics of one arm as data: what is published, polled and commanded (dvrk.md §2).

:class:`~davinci_sim.bridge.dvrk_node.DvrkNode` serves these tables; each entry names the
topic, its message type, the arm kinds that have it and how a message converts to the arm
call (commands) or a snapshot to a message (state topics).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from davinci_sim.bridge import dvrk_messages as m
from davinci_sim.sim.impedance import CartesianImpedance, HalfPlaneGains

if TYPE_CHECKING:
    from davinci_sim.sim.handle import ArmSnapshot

NODE = "/davinci_sim"
CRTK_VERSION = "1.1.0"  # dvrk.md 1.7
ALL = frozenset({"PSM", "ECM", "MTM", "SUJ"})
ARMS = frozenset({"PSM", "ECM", "MTM"})
PSM = frozenset({"PSM"})
MTM = frozenset({"MTM"})


@dataclass(frozen=True)
class ArmInfo:
    name: str
    arm_type: str
    joint_names: tuple[str, ...]


# =========================================================================== tables
@dataclass(frozen=True)
class StateTopic:
    """A topic built from the arm's snapshot."""

    suffix: str
    type: str
    build: Callable[[m.Dialect, ArmSnapshot, float, int], dict | None]
    arm_types: frozenset[str] = ALL


def _local_cv(d, a, t, s):
    return m.twist_stamped(d, m.local_twist(a.measured_cv, a.measured_cp), t, s)


STATE_TOPICS: tuple[StateTopic, ...] = (
    StateTopic("measured_js", "sensor_msgs/JointState",
               lambda d, a, t, s: m.joint_state(d, a.measured_js, t, s)),
    StateTopic("setpoint_js", "sensor_msgs/JointState",
               lambda d, a, t, s: m.joint_state(d, a.setpoint_js, t, s)),
    StateTopic("measured_cp", "geometry_msgs/PoseStamped",
               lambda d, a, t, s: m.pose_stamped(d, a.measured_cp, t, s)),
    StateTopic("setpoint_cp", "geometry_msgs/PoseStamped",
               lambda d, a, t, s: m.pose_stamped(d, a.setpoint_cp, t, s)),
    StateTopic("local/measured_cp", "geometry_msgs/PoseStamped",
               lambda d, a, t, s: m.pose_stamped(d, a.local_measured_cp, t, s)),
    StateTopic("local/setpoint_cp", "geometry_msgs/PoseStamped",
               lambda d, a, t, s: m.pose_stamped(d, a.local_setpoint_cp, t, s)),
    StateTopic("measured_cv", "geometry_msgs/TwistStamped",
               lambda d, a, t, s: m.twist_stamped(d, a.measured_cv, t, s), ARMS),
    StateTopic("local/measured_cv", "geometry_msgs/TwistStamped", _local_cv, ARMS),
    StateTopic("jaw/measured_js", "sensor_msgs/JointState",
               lambda d, a, t, s: m.joint_state(d, a.jaw_measured_js, t, s)
               if a.jaw_measured_js else None, PSM),
    StateTopic("jaw/setpoint_js", "sensor_msgs/JointState",
               lambda d, a, t, s: m.joint_state(d, a.jaw_setpoint_js, t, s)
               if a.jaw_setpoint_js else None, PSM),
    StateTopic("gripper/measured_js", "sensor_msgs/JointState",
               lambda d, a, t, s: m.joint_state(d, a.gripper_measured_js, t, s)
               if a.gripper_measured_js else None, MTM),
)  # fmt: skip


@dataclass(frozen=True)
class PolledTopic:
    """A topic whose value is asked from the loop (``target`` below the arm, ``method``)."""

    suffix: str
    type: str
    target: str
    method: str
    build: Callable[[m.Dialect, Any, str, float, int], dict]
    arm_types: frozenset[str] = ARMS


def _wrench(d, w, arm, t, s):
    return m.wrench_stamped(d, w, arm, t, s)


POLLED_TOPICS: tuple[PolledTopic, ...] = (
    PolledTopic("body/measured_cf", "geometry_msgs/WrenchStamped", "body", "measured_cf",
                _wrench),
    PolledTopic("spatial/measured_cf", "geometry_msgs/WrenchStamped", "spatial", "measured_cf",
                _wrench),
    PolledTopic("body/jacobian", "std_msgs/Float64MultiArray", "body", "jacobian",
                lambda d, J, arm, t, s: m.float64_multiarray(J)),
    PolledTopic("spatial/jacobian", "std_msgs/Float64MultiArray", "spatial", "jacobian",
                lambda d, J, arm, t, s: m.float64_multiarray(J)),
    PolledTopic("trajectory_j/ratio", "std_msgs/Float64", "", "trajectory_j_ratio",
                lambda d, r, arm, t, s: {"data": float(r)}),
    PolledTopic("orientation_locked", "std_msgs/Bool", "", "orientation_locked",
                lambda d, b, arm, t, s: {"data": bool(b)}, MTM),
)  # fmt: skip


@dataclass(frozen=True)
class CommandTopic:
    """A topic a client publishes to command the arm: ``target.method(*convert(msg))``."""

    suffix: str
    type: str
    target: str
    method: str
    convert: Callable[[dict, ArmInfo], tuple]
    arm_types: frozenset[str] = ARMS


def _positions(field: str):
    def convert(msg: dict, arm: ArmInfo) -> tuple:
        values = m.ordered(msg[field], msg["name"], arm.joint_names, field)
        return (values,)

    return convert


def _servo_jp(msg: dict, arm: ArmInfo) -> tuple:
    position = m.ordered(msg["position"], msg["name"], arm.joint_names, "position")
    velocity = msg["velocity"]
    if velocity:
        return position, m.ordered(velocity, msg["name"], arm.joint_names, "velocity")
    return (position,)


def _jaw(field: str):
    def convert(msg: dict, arm: ArmInfo) -> tuple:
        values = msg[field]
        if len(values) != 1:
            raise m.CommandError(f"jaw {field} needs exactly 1 value, got {len(values)}")
        return (values[0],)

    return convert


def _servo_cs(msg: dict, arm: ArmInfo) -> tuple:
    if not msg["pose_is_valid"]["data"]:
        raise m.CommandError("servo_cs: pose_is_valid is false; only pose goals are supported")
    T = m.pose_matrix(msg["pose"])
    if msg["twist_is_valid"]["data"]:
        return T, m.twist_vector(msg["twist"])
    return (T,)


def _quaternion(msg: dict, arm: ArmInfo) -> tuple:
    return (m.matrix_from_quaternion(msg["x"], msg["y"], msg["z"], msg["w"]),)


def _vector3(v: dict) -> np.ndarray:
    return np.array([v["x"], v["y"], v["z"]], dtype=float)


def _half_plane(g: dict) -> HalfPlaneGains:
    return HalfPlaneGains(_vector3(g["p"]), _vector3(g["d"]), _vector3(g["bias"]),
                          _vector3(g["deadband"]))  # fmt: skip


def _impedance(msg: dict, arm: ArmInfo) -> tuple:
    """``crtk_msgs/CartesianImpedance`` -> :class:`CartesianImpedance` (reference frame)."""
    fo, to = msg["force_orientation"], msg["torque_orientation"]
    return (
        CartesianImpedance(
            force_position=_vector3(msg["force_position"]),
            force_orientation=m.matrix_from_quaternion(fo["x"], fo["y"], fo["z"], fo["w"]),
            torque_orientation=m.matrix_from_quaternion(to["x"], to["y"], to["z"], to["w"]),
            position_positive=_half_plane(msg["position_positive"]),
            position_negative=_half_plane(msg["position_negative"]),
            orientation_positive=_half_plane(msg["orientation_positive"]),
            orientation_negative=_half_plane(msg["orientation_negative"]),
        ),
    )


COMMAND_TOPICS: tuple[CommandTopic, ...] = (
    CommandTopic("state_command", "crtk_msgs/StringStamped", "", "state_command",
                 lambda msg, a: (msg["string"],), ALL),
    CommandTopic("hold", "std_msgs/Empty", "", "hold", lambda msg, a: (), ALL),
    CommandTopic("free", "std_msgs/Empty", "", "free", lambda msg, a: ()),
    CommandTopic("servo_jp", "sensor_msgs/JointState", "", "servo_jp", _servo_jp, ALL),
    CommandTopic("servo_jr", "sensor_msgs/JointState", "", "servo_jr", _positions("position")),
    CommandTopic("move_jp", "sensor_msgs/JointState", "", "move_jp", _positions("position"),
                 ALL),
    CommandTopic("move_jr", "sensor_msgs/JointState", "", "move_jr", _positions("position")),
    CommandTopic("servo_jf", "sensor_msgs/JointState", "", "servo_jf", _positions("effort")),
    CommandTopic("servo_cp", "geometry_msgs/PoseStamped", "", "servo_cp",
                 lambda msg, a: (m.pose_matrix(msg["pose"]),)),
    CommandTopic("servo_cs", "crtk_msgs/CartesianState", "", "servo_cp", _servo_cs),
    CommandTopic("move_cp", "geometry_msgs/PoseStamped", "", "move_cp",
                 lambda msg, a: (m.pose_matrix(msg["pose"]),)),
    CommandTopic("body/servo_cf", "geometry_msgs/WrenchStamped", "body", "servo_cf",
                 lambda msg, a: (m.wrench_vector(msg["wrench"]),)),
    CommandTopic("spatial/servo_cf", "geometry_msgs/WrenchStamped", "spatial", "servo_cf",
                 lambda msg, a: (m.wrench_vector(msg["wrench"]),)),
    CommandTopic("use_gravity_compensation", "std_msgs/Bool", "", "use_gravity_compensation",
                 lambda msg, a: (msg["data"],)),
    CommandTopic("set_base_frame", "geometry_msgs/PoseStamped", "", "set_base_frame",
                 lambda msg, a: (m.pose_matrix(msg["pose"]), msg["header"]["frame_id"])),
    CommandTopic("trajectory_j/set_ratio", "std_msgs/Float64", "", "trajectory_j_set_ratio",
                 lambda msg, a: (msg["data"],)),
    CommandTopic("body/set_cf_orientation_absolute", "std_msgs/Bool", "",
                 "body_set_cf_orientation_absolute", lambda msg, a: (msg["data"],)),
    CommandTopic("jaw/servo_jp", "sensor_msgs/JointState", "jaw", "servo_jp", _jaw("position"),
                 PSM),
    CommandTopic("jaw/move_jp", "sensor_msgs/JointState", "jaw", "move_jp", _jaw("position"),
                 PSM),
    CommandTopic("jaw/servo_jf", "sensor_msgs/JointState", "jaw", "servo_jf", _jaw("effort"),
                 PSM),
    CommandTopic("lock_orientation", "geometry_msgs/Quaternion", "", "lock_orientation",
                 _quaternion, MTM),
    CommandTopic("unlock_orientation", "std_msgs/Empty", "", "unlock_orientation",
                 lambda msg, a: (), MTM),
    CommandTopic("servo_ci", "crtk_msgs/CartesianImpedance", "", "servo_ci", _impedance, MTM),
)  # fmt: skip

#: Latched constants (dvrk.md 1.2, 1.4: the simulated tool and endoscope).
CONSTANT_TOPICS = {
    "PSM": ("tool_type", "LARGE_NEEDLE_DRIVER:400006"),
    "ECM": ("endoscope_type", "Classic_SD_STRAIGHT"),
}
#: ``gripper/closed`` threshold, rad: the dVRK's ``gripper_events_zero`` default 0 (dvrk.md
#: 2.2) plus 0.3° because the simulated fingers settle a hair above their closed stop.
GRIPPER_CLOSED_BELOW = 0.005

EVENT_TOPICS = {"error": "std_msgs/String", "warning": "std_msgs/String",
                "status": "std_msgs/String"}  # fmt: skip
