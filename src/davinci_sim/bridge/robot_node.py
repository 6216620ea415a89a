"""The robot for Foxglove, RViz and ``robot_state_publisher`` users: its description, every
frame on ``/tf`` and the joint states (what ``robot_state_publisher`` gives on a real robot).

* ``/robot_description`` (``std_msgs/String``, latched: a new subscriber gets it at once, as
  ROS 2's transient-local topic) and the ROS 1 parameter ``/robot_description``: the URDF of
  the running model (:mod:`davinci_sim.model.urdf`: cart, setup joints, PSMs, ECM, console and
  MTMs, cameras; the dVRK's joint names);
* ``/<ARM>/robot_description`` (latched, and parameters): each arm alone (``PSM1``,
  ``SUJ/PSM1`` …), as the dVRK's launch files describe them: the same link names, so they
  draw from the same ``/tf``, and the joints named as ``/<ARM>/measured_js`` names them;
* ``/tf_static`` (``tf2_msgs/TFMessage``, latched): every fixed joint, once;
* ``/tf`` at ``rate`` (50 Hz, the dVRK's tf rate) while someone subscribes: every moving
  joint (the setup joints, every arm joint, the jaws' fingers, the MTM grippers, and the
  parallelograms' mimic links), beside the ``measured_cp`` frames the dVRK node publishes
  on the same topic. The tree is rooted at ``world``; ``Cart`` and ``HRSV`` are its links, so
  ``measured_cp`` (``Cart`` → ``ECM``, ``ECM`` → ``PSM1``, ``HRSV`` → ``MTML`` …) hangs in it;
* ``/joint_states`` (``sensor_msgs/JointState``) at the same rate while subscribed: every
  moving joint of the URDF (mimic joints excluded, as ``joint_state_publisher`` does), so a
  ``robot_state_publisher`` fed from it reproduces ``/tf``.

The messages are built by pure functions (:func:`tf_message`, :func:`static_tf_message`,
:func:`joint_state_message`) that another transport (client mode) can publish as they are.

The values are the simulation's joint positions, ``qpos`` (exact, where ``measured_js``
may carry encoder noise): the snapshots must carry them (``extras["qpos"]``, the system
built with ``publish_qpos``; ``serve`` does so whenever the server runs).
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable, Mapping
from types import SimpleNamespace
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from davinci_sim.bridge.rosbridge.publisher import PeriodicTask
from davinci_sim.model.urdf import Robot, robot_from_model

if TYPE_CHECKING:
    import mujoco

    from davinci_sim.bridge.rosbridge.core import Bridge
    from davinci_sim.bridge.rosbridge.dialect import Dialect
    from davinci_sim.sim.handle import SimHandle

_log = logging.getLogger("davinci_sim.bridge")

NODE = "/davinci_sim/robot_state_publisher"


class RobotNode:
    """Serves the robot's description, ``/tf``, ``/tf_static`` and ``/joint_states``.

    Args:
        handle: the running simulation (its snapshots carry ``extras["qpos"]``).
        model: the simulation's compiled model, or a callable returning it (e.g.
            ``System.model_source``).
        rate: publish rate of ``/tf`` and ``/joint_states``, Hz (the dVRK's tf rate, 50).
    """

    def __init__(
        self,
        handle: SimHandle,
        model: mujoco.MjModel | Callable[[], mujoco.MjModel],
        *,
        rate: float = 50.0,
    ) -> None:
        if not 0 < rate <= 1000:
            raise ValueError(f"rate must be in ]0, 1000] Hz, got {rate!r}")
        self.handle = handle
        self.rate = rate
        m = model() if callable(model) else model
        self.nq = int(m.nq)
        self.robot: Robot = robot_from_model(m)
        self.urdf = self.robot.to_xml()
        self.arm_urdfs = {arm: self.robot.arm(arm).to_xml() for arm in self.robot.arms}
        self.moving = [j for j in self.robot.joints if j.type != "fixed"]
        self.published = 0
        self._warned = False
        self._task: PeriodicTask | None = None

    # ------------------------------------------------------------------ setup
    def attach(self, bridge: Bridge) -> None:
        self.bridge = bridge
        d = bridge.dialect
        description = bridge.advertise("/robot_description", "std_msgs/String", node=NODE,
                                       latch=True)  # fmt: skip
        bridge.publish(description, {"data": self.urdf})
        bridge.params["/robot_description"] = json.dumps(self.urdf)
        for arm, urdf in self.arm_urdfs.items():  # each arm alone, as the dVRK describes it
            topic = bridge.advertise(f"/{arm}/robot_description", "std_msgs/String", node=NODE,
                                     latch=True)  # fmt: skip
            bridge.publish(topic, {"data": urdf})
            bridge.params[f"/{arm}/robot_description"] = json.dumps(urdf)
        static = bridge.advertise("/tf_static", "tf2_msgs/TFMessage", node=NODE, latch=True)
        stamp = self._stamp(self.handle.snapshot().time)
        bridge.publish(static, static_tf_message(self.robot, d, stamp))
        self.tf = bridge.advertise("/tf", "tf2_msgs/TFMessage", node=NODE)
        self.joint_states = bridge.advertise("/joint_states", "sensor_msgs/JointState", node=NODE)
        self._task = PeriodicTask(1.0 / self.rate, self._publish)
        self._task.start()

    async def detach(self) -> None:
        if self._task is not None:
            await self._task.stop()
        for name in ("", *(f"/{arm}" for arm in self.arm_urdfs)):
            self.bridge.params.pop(f"{name}/robot_description", None)
        self.bridge.remove_node(NODE)

    # ------------------------------------------------------------------ publishing
    def _stamp(self, sim_time: float) -> float:
        return sim_time if self.bridge.config.stamp_clock == "sim" else time.time()

    def _publish(self) -> None:
        if not (self.tf.subscriptions or self.joint_states.subscriptions):
            return
        snap = self.handle.snapshot()
        qpos = snap.extras.get("qpos")
        if qpos is None or len(qpos) != self.nq:
            if not self._warned:
                self._warned = True
                _log.warning("/tf and /joint_states: the snapshots carry no qpos of %d values "
                             "(build the system with publish_qpos=True)", self.nq)  # fmt: skip
            return
        values = self.robot.joint_values(qpos)
        stamp = self._stamp(snap.time)
        d = self.bridge.dialect
        if self.joint_states.subscriptions:
            seq = self.joint_states.next_seq()
            self.bridge.publish(self.joint_states, joint_state_message(values, d, stamp, seq))
        if self.tf.subscriptions:
            self.bridge.publish(self.tf, tf_message(self.robot, values, d, stamp))
        self.published += 1


# =========================================================================== messages
def _transforms(d: Dialect, joints, T: np.ndarray, stamp: float, prefix: str = "") -> list[dict]:
    """``geometry_msgs/TransformStamped`` of each joint: its child's pose ``T[i]`` (n, 4, 4)
    in its parent; both frames named with ``prefix`` in front (a tf_prefix, ``""``: none)."""
    xyz = T[:, :3, 3].tolist()
    quat = Rotation.from_matrix(T[:, :3, :3]).as_quat().tolist()  # (x, y, z, w)
    header = d.header(stamp, "", 0)
    return [
        {
            "header": {**header, "frame_id": prefix + j.parent},
            "child_frame_id": prefix + j.child,
            "transform": {
                "translation": {"x": p[0], "y": p[1], "z": p[2]},
                "rotation": {"x": r[0], "y": r[1], "z": r[2], "w": r[3]},
            },
        }
        for j, p, r in zip(joints, xyz, quat, strict=True)
    ]


def tf_message(
    robot: Robot, values: Mapping[str, float], d: Dialect, stamp: float, frame_prefix: str = ""
) -> dict:
    """``tf2_msgs/TFMessage`` of every moving joint of ``robot`` at the joint ``values``
    (rad, m; see :meth:`~davinci_sim.model.urdf.Robot.moving_transforms`); every frame named
    ``frame_prefix + link`` (as ``robot_state_publisher``'s ``frame_prefix``)."""
    T = robot.moving_transforms(values)
    return {"transforms": _transforms(d, robot.moving, T, stamp, frame_prefix)}


def static_tf_message(robot: Robot, d: Dialect, stamp: float, frame_prefix: str = "") -> dict:
    """``tf2_msgs/TFMessage`` of every fixed joint of ``robot`` (``/tf_static``), frames
    named ``frame_prefix + link``. With a prefix it also holds the identity from the plain
    root to the prefixed one (``world`` → ``sim/world``, what a ``static_transform_publisher``
    beside a prefixed ``robot_state_publisher`` gives), so the tree hangs in ``world``."""
    fixed = [j for j in robot.joints if j.type == "fixed"]
    T = np.stack([j.T_parent_origin for j in fixed])
    if frame_prefix:
        root = SimpleNamespace(parent=robot.root, child=robot.root)
        fixed.insert(0, root)  # (its child, not its parent, gets the prefix below)
        T = np.concatenate([np.eye(4)[None], T])
    transforms = _transforms(d, fixed, T, stamp, frame_prefix)
    if frame_prefix:
        transforms[0]["header"]["frame_id"] = robot.root
    return {"transforms": transforms}


def joint_state_message(values: Mapping[str, float], d: Dialect, stamp: float, seq: int = 0):
    """``sensor_msgs/JointState`` of the joint ``values`` (URDF joint name → rad or m)."""
    return {
        "header": d.header(stamp, "", seq),
        "name": list(values),
        "position": [float(v) for v in values.values()],
        "velocity": [],
        "effort": [],
    }
