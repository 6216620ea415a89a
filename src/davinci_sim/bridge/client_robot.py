"""The robot on the remote in client mode: what ``robot_state_publisher`` gives on a real
robot, so RViz (or Foxglove) on the remote ROS system shows the simulated arms moving.

:class:`RosClientMode` publishes, through the remote's rosbridge_server, with the built-in
server's own message builders (:mod:`davinci_sim.bridge.robot_node`, one code path):

* ``{ns}/robot_description`` (``std_msgs/String``) and ``{ns}/<ARM>/robot_description`` for
  each simulated arm the client publishes (PSMs, ECM, SUJ …), latched: advertised with
  ``latch``, which a ROS 1 rosbridge turns into a latched publisher and a ROS 2 rosbridge
  into a transient-local publisher of depth 1 without lifespan (rosbridge.md), so RViz's
  RobotModel display gets it when it subscribes later. On a ROS 1 remote the same URDFs also
  go into the parameters of those names (``/rosapi/set_param``; a warning says so if the
  remote has no rosapi or refuses), where RViz 1 reads them. ROS 2 has no global parameter
  server: there the topic is the description, as ``robot_state_publisher`` does it;
* ``/tf_static`` (latched, one message with every fixed joint) and ``/tf`` at ``rate`` (every
  moving joint) — the global topics, the only ones RViz's tf listener reads;
* ``{ns}/joint_states`` at the same rate and stamp: every actuated joint of the URDF.

Frames with a namespace, a ``tf_prefix`` scheme (``robot_state_publisher``'s
``frame_prefix``): ``/sim`` prefixes every frame with ``sim/`` (``sim/world``,
``sim/PSM1_yaw_link`` …), so the simulated robot never takes a frame of the real robot
publishing on the same ``/tf``; ``/tf_static`` also carries the identity ``world`` →
``sim/world``, so the simulated robot stands in the remote's ``world`` (over the real one:
a ghost of the real robot). The descriptions keep the plain link names: RViz's RobotModel
display is given the prefix in its *TF Prefix* field (``sim``) and the description in its
topic (ROS 2, ``/sim/robot_description``) or parameter (ROS 1) field. With namespace ``/``
the names are the plain ones (the simulated robot is *the* robot of the remote).

The joint values are the simulation's ``qpos`` (exact, as :class:`~davinci_sim.bridge.
robot_node.RobotNode` publishes them): the snapshots must carry ``extras["qpos"]``.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterable

from davinci_sim.bridge.robot_node import joint_state_message, static_tf_message, tf_message
from davinci_sim.model.urdf import Robot

_log = logging.getLogger("davinci_sim.bridge.client")

#: ``send(topic, type, message, latch)``: publish one message on the remote.
Send = Callable[[str, str, dict, bool], None]


def frame_prefix(namespace: str) -> str:
    """The tf prefix of a client-mode namespace: ``/sim`` → ``sim/``, ``/a/b`` → ``a/b/``,
    ``/`` → ``""`` (plain frame names)."""
    return "" if namespace == "/" else namespace.strip("/") + "/"


class ClientRobot:
    """``robot_state_publisher`` on the remote for :class:`~davinci_sim.bridge.client_mode.
    RosClientMode` (which owns the connection and calls :meth:`start` then :meth:`tick`).

    Args:
        robot: the URDF robot of the simulation's model.
        nq: the model's number of ``qpos`` values (to check the snapshots' ``qpos``).
        namespace: the client mode's namespace (``/`` for none).
        arms: the simulated arms the client publishes: each of them that the robot
            describes also gets its ``{ns}/<ARM>/robot_description``.
        dialect: the remote's message dialect.
    """

    def __init__(self, robot: Robot, nq: int, namespace: str, arms: Iterable[str], dialect):
        self.robot = robot
        self.nq = nq
        self.dialect = dialect
        self.prefix = "" if namespace == "/" else namespace
        self.frame_prefix = frame_prefix(namespace)
        self.urdfs = {f"{self.prefix}/robot_description": robot.to_xml()}
        for arm in arms:
            if arm in robot.arms:
                self.urdfs[f"{self.prefix}/{arm}/robot_description"] = robot.arm(arm).to_xml()
        self.joint_states = f"{self.prefix}/joint_states"
        self.published = 0
        self._seq = 0
        self._warned = False

    @property
    def names(self) -> set[str]:
        """Every topic this publishes on the remote (for client mode's echo safety)."""
        return {*self.urdfs, "/tf", "/tf_static", self.joint_states}

    def start(self, send: Send, ros=None, ros_version: int = 2, timeout: float = 5.0) -> None:
        """The latched messages (descriptions, ``/tf_static``) and, on a ROS 1 remote
        (``ros``: the roslibpy connection), the description parameters; waits up to
        ``timeout`` s for the remote to answer the parameters (a warning if not)."""
        for name, urdf in self.urdfs.items():
            send(name, "std_msgs/String", {"data": urdf}, True)
        msg = static_tf_message(self.robot, self.dialect, time.time(), self.frame_prefix)
        send("/tf_static", "tf2_msgs/TFMessage", msg, True)
        if ros is not None and ros_version == 1:
            self._set_params(ros, timeout)

    def _set_params(self, ros, timeout: float) -> None:
        import roslibpy

        lock = threading.Lock()
        answered = threading.Event()
        left, failed = [len(self.urdfs)], []

        def done(name: str, error: object = None) -> None:
            with lock:
                if error is not None:
                    failed.append(f"{name} ({error})")
                left[0] -= 1
                if left[0] == 0:
                    answered.set()

        for name, urdf in self.urdfs.items():
            roslibpy.Param(ros, name).set(
                urdf, lambda _, n=name: done(n), lambda e, n=name: done(n, e or "refused")
            )
        if not answered.wait(timeout):
            _log.warning("client mode: the remote did not answer /rosapi/set_param in %.0f s: "
                         "the robot_description parameters may be unset (RViz 1 reads them; "
                         "the latched topics carry the same URDFs)", timeout)  # fmt: skip
        elif failed:
            _log.warning("client mode: the remote refused the robot_description parameters "
                         "%s: RViz 1 cannot read them (the latched topics carry the same "
                         "URDFs)", ", ".join(failed))  # fmt: skip
        else:
            _log.info("client mode: robot_description parameters set on the remote")

    def tick(self, snap, send: Send) -> bool:
        """Publish ``/tf`` and ``{ns}/joint_states`` of ``snap`` (one wall-clock stamp for
        both, as the client mode stamps the arms' states); False if it carries no ``qpos``
        (said once)."""
        qpos = (snap.extras or {}).get("qpos")
        if qpos is None or len(qpos) != self.nq:
            if not self._warned:
                self._warned = True
                _log.warning("client mode: /tf and %s: the snapshots carry no qpos of %d "
                             "values (build the system with publish_qpos=True)",
                             self.joint_states, self.nq)  # fmt: skip
            return False
        values = self.robot.joint_values(qpos)
        d, stamp = self.dialect, time.time()
        self._seq += 1
        send(self.joint_states, "sensor_msgs/JointState",
             joint_state_message(values, d, stamp, self._seq), False)  # fmt: skip
        send("/tf", "tf2_msgs/TFMessage",
             tf_message(self.robot, values, d, stamp, self.frame_prefix), False)  # fmt: skip
        self.published += 1
        return True
