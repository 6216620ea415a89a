"""Client mode: the simulator joins an existing ROS system through its rosbridge_server.

As the seed's Unity simulator does, the simulator connects as a rosbridge client (roslibpy)
to ``ws://HOST:9090`` and:

* subscribes the real console's MTMs (``/<MTM>/measured_cp``, ``/<MTM>/measured_js``,
  ``/<MTM>/gripper/measured_js``) and pedals (``/footpedals/<pedal>``,
  ``/console/operator_present``; dvrk.md 2.2, 2.3). With a network master device in the
  simulation (a component ``<MTM>/device`` whose snapshot ``kind`` is ``network``, issue 3),
  poses, gripper and pedals are pushed into it, so the simulated teleoperation follows the
  real MTMs. Without one, the simulated MTM arms are servoed to the real MTMs' joints.
* publishes the guidance wrench that the simulation sends to each master device to the real
  MTM's ``body/servo_cf`` (rotated from display axes into the handle's body frame), only
  while it is non-zero (plus one zero to release), so an idle simulation never switches a
  real MTM into effort mode;
* publishes the simulated PSM, ECM and SUJ states (``measured_js``, ``measured_cp``,
  ``setpoint_cp``, ``jaw/measured_js``, ``operating_state``, and the arms' ``error``,
  ``warning``, ``status`` events) under a namespace (``/sim``; ``/`` for none, so that the
  simulated arms take the real arms' names) so dVRK tools see them next to the real robot's;
* takes the commands published on the remote for the simulated arms: every CRTK command
  topic the built-in server serves (``{ns}/<ARM>/state_command``, ``servo_*``, ``move_*``,
  ``jaw/*``, ``body/servo_cf`` …, :data:`~davinci_sim.bridge.dvrk_topics.COMMAND_TOPICS`),
  the console's and teleoperations' commands (``{ns}/console/teleop/enable``,
  ``{ns}/MTMR_PSM1/state_command`` …) and the system's (``{ns}/system/home`` …). They go
  through the built-in server's own code (:func:`~davinci_sim.bridge.dvrk_commands.
  command_sender`), so they are converted, checked and refused the same way; as client mode
  cannot send a ``status`` to whoever published, a refusal goes on ``{ns}/<ARM>/error`` with
  the text the built-in server publishes there (``<ARM>: <why>``);
* publishes the robot as ``robot_state_publisher`` would (:mod:`davinci_sim.bridge.
  client_robot`): ``{ns}/robot_description`` latched (and the ROS 1 parameter),
  ``/tf_static``, ``/tf`` and ``{ns}/joint_states`` at ``tf_rate``, the frames prefixed
  ``sim/`` for namespace ``/sim`` (``robot=False``: none of it, to save the bandwidth).

Echo safety: the simulator never subscribes to a topic it publishes on the remote (it would
take its own messages as commands). The two sets of names are computed before connecting and
a configuration where they meet (e.g. namespace ``/`` with a simulated ``MTMR`` that also
follows the real ``MTMR``) is refused with a :class:`ValueError` naming the topics.

Size: under 600 lines because it is one connection with its two directions (what the
remote sends in, what the simulation sends out) and the plan of names that keeps them apart;
the conversions themselves live in the tables and senders it shares with the built-in server,
the robot's messages in :mod:`~davinci_sim.bridge.client_robot`.
"""

from __future__ import annotations

import logging
import queue
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from davinci_sim.bridge import dvrk_messages as m
from davinci_sim.bridge.client_robot import ClientRobot
from davinci_sim.bridge.console_node import (
    CONSOLE_COMMANDS,
    TELEOP_ECM_COMMANDS,
    TELEOP_PSM_COMMANDS,
    component_sender,
    kind_of,
)
from davinci_sim.bridge.dvrk_commands import Refusal, command_sender, error_text
from davinci_sim.bridge.dvrk_topics import COMMAND_TOPICS, EVENT_TOPICS, ArmInfo
from davinci_sim.bridge.rosbridge.convert import MessageError, from_wire
from davinci_sim.bridge.rosbridge.dialect import dialect
from davinci_sim.bridge.rosbridge.types import TypeRegistry
from davinci_sim.bridge.system_node import COMMANDS as SYSTEM_COMMANDS
from davinci_sim.model.urdf import robot_from_model

if TYPE_CHECKING:
    import mujoco

    from davinci_sim.sim.handle import SimHandle, Snapshot

_log = logging.getLogger("davinci_sim.bridge.client")

PEDAL_TOPICS = {
    "clutch": "/footpedals/clutch",
    "camera": "/footpedals/camera",
    "coag": "/footpedals/coag",
    "cam_minus": "/footpedals/cam_minus",
    "cam_plus": "/footpedals/cam_plus",
    "bicoag": "/footpedals/bicoag",
    "operator_present": "/console/operator_present",
}
"""Pedal/button → topic on the real system (dvrk.md 2.3)."""

#: ``wrench_source(snapshot) -> {mtm: wrench (6,) in HRSV axes}``.
WrenchSource = Callable[["Snapshot"], dict[str, np.ndarray]]


@dataclass(frozen=True)
class ClientModeConfig:
    """Options of :class:`RosClientMode`."""

    url: str
    """The remote rosbridge_server, ``ws://HOST:9090``."""
    namespace: str = "/sim"
    """Prefix of the simulated arms' topics on the remote system (``/``: none)."""
    mtms: tuple[str, ...] = ("MTML", "MTMR")
    """Real MTMs to follow (same names as the simulated ones)."""
    arms: tuple[str, ...] | None = None
    """Simulated arms to publish and command (default: every PSM, the ECM, the SUJ arms and
    the simulated MTMs not in ``mtms``)."""
    commands: bool = True
    """Take the commands published on the remote for the simulated arms, the console and
    the system (False: publish states only)."""
    rate: float = 50.0
    """Publish rate of the simulated states, Hz."""
    wrench_rate: float = 100.0
    """Publish rate of the guidance wrench, Hz."""
    ros_version: Literal[1, 2] = 2
    """Dialect of the remote system."""
    robot: bool = True
    """Publish the robot's description, ``/tf``, ``/tf_static`` and ``{ns}/joint_states``
    (:mod:`~davinci_sim.bridge.client_robot`); needs the model and ``qpos`` snapshots."""
    tf_rate: float = 50.0
    """Publish rate of ``/tf`` and ``{ns}/joint_states``, Hz (the dVRK's tf rate)."""
    drive: Literal["auto", "device", "joints"] = "auto"
    """How the real MTMs drive the simulation: through the network master devices
    (``device``), by servoing the simulated MTM arms (``joints``), or ``auto``."""

    def __post_init__(self) -> None:
        if not self.url.startswith(("ws://", "wss://")):
            raise ValueError(f"url must be ws://HOST:PORT, got {self.url!r}")
        if not all(0 < r <= 1000 for r in (self.rate, self.wrench_rate, self.tf_rate)):
            raise ValueError("rate, wrench_rate and tf_rate must be in ]0, 1000] Hz")
        if self.drive not in ("auto", "device", "joints"):
            raise ValueError(f"drive must be auto, device or joints, got {self.drive!r}")
        if not self.namespace.startswith("/") or (
            self.namespace != "/" and self.namespace.endswith("/")
        ):
            raise ValueError(
                f"namespace must start with '/' (and not end with one, unless it is '/'), "
                f"got {self.namespace!r}"
            )


def default_wrench_source(snap: Snapshot) -> dict[str, np.ndarray]:
    """The wrench each network master device ``<MTM>/device`` renders (issue 3)."""
    out = {}
    for name, state in (snap.extras or {}).items():
        if name.endswith("/device") and getattr(state, "wrench", None) is not None:
            out[name.split("/")[0]] = np.asarray(state.wrench, dtype=float)
    return out


#: Sends waiting in the process's Twisted reactor (roslibpy queues each publish there) above
#: which the client mode skips a period of its streams: a remote that reads slower than the
#: streams come, or a closed connection, would otherwise grow the queue without bound.
MAX_BACKLOG = 500


def send_backlog() -> int:
    """Calls queued for the Twisted reactor's thread (roslibpy's sends, connects, closes) in
    this process; 0 before roslibpy's reactor is imported."""
    reactor = sys.modules.get("twisted.internet.reactor")
    return len(getattr(reactor, "threadCallQueue", ()))


class RosClientMode:
    """The simulator as a client of a remote rosbridge (see the module docstring).

    Args:
        handle: the running simulation.
        config: where to connect and what to exchange.
        wrench_source: the guidance wrench per MTM (default: the network devices').
        model: the simulation's compiled model, or a callable returning it (e.g.
            ``System.model_source``), for the robot's description (``config.robot``;
            default: the in-process simulation's, ``handle.sim.model``).

    Raises:
        ValueError: the topics it would publish and those it would take meet (echo), or
            ``config.robot`` without a model.
    """

    def __init__(
        self,
        handle: SimHandle,
        config: ClientModeConfig,
        *,
        wrench_source: WrenchSource = default_wrench_source,
        model: mujoco.MjModel | Callable[[], mujoco.MjModel] | None = None,
    ) -> None:
        self.handle = handle
        self.config = config
        self.wrench_source = wrench_source
        self.dialect = dialect(config.ros_version)
        self.registry = TypeRegistry(self.dialect)
        self.ros: Any = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._remote_R: dict[str, np.ndarray] = {}
        self._wrench_on: dict[str, bool] = {}
        self._last_state: dict[str, tuple] = {}
        self._topics: dict[str, Any] = {}
        self._subscribed: list[Any] = []
        self._outbox: queue.SimpleQueue[tuple[str, str, dict]] = queue.SimpleQueue()
        self._unsubscribe: Callable[[], None] | None = None
        self.received: dict[str, int] = {}
        self.errors = 0
        self.skipped = 0
        """Periods whose streamed states were not sent: the connection's queue was full
        (:data:`MAX_BACKLOG`) or closed."""
        self.prefix = "" if config.namespace == "/" else config.namespace
        snap = handle.snapshot()
        self.arms = config.arms or tuple(
            n
            for n, a in snap.arms.items()
            if a.arm_type in ("PSM", "ECM", "SUJ") or (a.arm_type == "MTM" and n not in config.mtms)
        )
        self.mode: dict[str, str] = {}
        for mtm in config.mtms:
            device = (snap.extras or {}).get(f"{mtm}/device")
            is_network = getattr(device, "kind", None) == "network"
            if config.drive == "device" and not is_network:
                raise ValueError(f"drive='device' needs a network device '{mtm}/device'")
            self.mode[mtm] = "device" if (is_network and config.drive != "joints") else "joints"
        self.has_console = "console" in (snap.extras or {})
        self.robot = self._robot(model, snap) if config.robot else None
        self._plan = self._plan_subscriptions(snap)
        self.published_names = self._plan_publications(snap)
        echo = sorted(set(self._plan) & self.published_names)
        if echo:
            raise ValueError(
                f"client mode would take its own messages as input on {echo}: choose another "
                "namespace, or leave these arms out of 'arms' or 'mtms'"
            )

    def _robot(self, model, snap: Snapshot) -> ClientRobot:
        if model is None:
            model = getattr(getattr(self.handle, "sim", None), "model", None)
        if model is None:
            raise ValueError("client mode publishes the robot from the simulation's model: "
                             "give model=…, or robot=False")  # fmt: skip
        m_ = model() if callable(model) else model
        arms = [a for a in self.arms if a in snap.arms]
        return ClientRobot(robot_from_model(m_), int(m_.nq), self.config.namespace, arms,
                           self.dialect)  # fmt: skip

    def _arm_topic(self, arm: str, suffix: str) -> str:
        return f"{self.prefix}/{arm}/{suffix}"

    def _plan_publications(self, snap: Snapshot) -> set[str]:
        """Every topic name this client may publish on the remote."""
        names = {f"/{mtm}/body/servo_cf" for mtm in self.config.mtms}
        for arm in self.arms:
            if arm in snap.arms:
                names |= {self._arm_topic(arm, s) for s in (
                    "measured_js", "measured_cp", "setpoint_cp", "jaw/measured_js",
                    "operating_state", *EVENT_TOPICS)}  # fmt: skip
        if self.robot is not None:
            names |= self.robot.names
        return names

    def _plan_subscriptions(self, snap: Snapshot) -> dict[str, tuple[str, Callable, Callable]]:
        """``{topic: (type, on_message(value), on_invalid(error text))}`` on the remote."""
        plan: dict[str, tuple[str, Callable, Callable]] = {}
        log = self._log_refusal
        for mtm in self.config.mtms:
            plan[f"/{mtm}/measured_cp"] = (
                "geometry_msgs/PoseStamped",
                lambda msg, mtm=mtm: self._on_pose(mtm, msg),
                log,
            )
            plan[f"/{mtm}/measured_js"] = (
                "sensor_msgs/JointState",
                lambda msg, mtm=mtm: self._on_joints(mtm, msg),
                log,
            )
            plan[f"/{mtm}/gripper/measured_js"] = (
                "sensor_msgs/JointState",
                lambda msg, mtm=mtm: self._on_gripper(mtm, msg),
                log,
            )
        for button, topic in PEDAL_TOPICS.items():
            plan[topic] = ("sensor_msgs/Joy", lambda msg, b=button: self._on_button(b, msg), log)
        if not self.config.commands:
            return plan
        for name in self.arms:
            a = snap.arms.get(name)
            if a is None:
                continue
            info = ArmInfo(name, a.arm_type, tuple(a.measured_js.name))
            for spec in COMMAND_TOPICS:
                if a.arm_type in spec.arm_types:
                    send = command_sender(self.handle, info, spec)
                    refused = lambda r, arm=name: self._refused(arm, r)  # noqa: E731
                    plan[self._arm_topic(name, spec.suffix)] = (
                        spec.type,
                        lambda msg, send=send, refused=refused: send(msg, refused),
                        lambda text, refused=refused: refused(Refusal(text, True)),
                    )
        for component, state in (snap.extras or {}).items():
            kind = kind_of(state)
            if kind is None:
                continue
            where, commands = {
                "console": ("console", CONSOLE_COMMANDS),
                "teleop_psm": (component, TELEOP_PSM_COMMANDS),
                "teleop_ecm": (component, TELEOP_ECM_COMMANDS),
            }[kind]
            for cmd in commands:
                send = component_sender(self.handle, component, cmd)
                plan[f"{self.prefix}/{where}/{cmd.suffix}"] = (
                    cmd.type, lambda msg, send=send: send(msg, log), log)  # fmt: skip
        for name, commands in SYSTEM_COMMANDS.items():
            for where in ("system", "console"):
                plan[f"{self.prefix}/{where}/{name}"] = (
                    "std_msgs/Empty",
                    lambda msg, c=commands: self._on_system(c),
                    log,
                )
        return plan

    # ------------------------------------------------------------------ lifecycle
    def start(self, timeout: float = 10.0) -> RosClientMode:
        import roslibpy

        c = self.config
        self.ros = roslibpy.Ros(c.url)
        self.ros.run(timeout)
        for mtm in c.mtms:
            if self.mode[mtm] == "joints" and mtm in self.handle.snapshot().arms:
                self.handle.call(mtm, "state_command", "enable")
                self.handle.call(mtm, "state_command", "home")
        self._unsubscribe = self.handle.subscribe(self._on_event)
        for name, (type_name, on_message, on_invalid) in self._plan.items():
            self._sub(name, type_name, on_message, on_invalid)
        self._await_subscriptions(timeout)
        if self.robot is not None:  # the latched messages, before the thread owns the topics
            self.robot.start(self._send, self.ros, c.ros_version, timeout)
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="ros-client-mode", daemon=True)
        self._thread.start()
        _log.info("client mode: connected to %s (namespace %s)", c.url, c.namespace)
        return self

    def _await_subscriptions(self, timeout: float) -> None:
        """Return once the remote has the subscriptions, so that a command published after
        :meth:`start` is not lost: a rosbridge server handles one client's operations in
        order, so the answer to a ``/rosapi/topics`` call sent after them comes after them.
        A remote without rosapi only costs the timeout (and a warning)."""
        import roslibpy

        answered = threading.Event()
        roslibpy.Service(self.ros, "/rosapi/topics", "rosapi/Topics").call(
            roslibpy.ServiceRequest(), lambda _: answered.set(), lambda _: answered.set()
        )
        if not answered.wait(timeout):
            _log.warning("client mode: no answer from /rosapi/topics on %s in %.0f s; the "
                         "first commands may be lost", self.config.url, timeout)  # fmt: skip

    def stop(self) -> None:
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5)
            self._thread = None
        if self.ros is not None:
            for topic in self._subscribed:
                topic.unsubscribe()
            for topic in self._topics.values():
                topic.unadvertise()
            try:
                self.ros.close()
            except Exception:
                pass
            self.ros = None

    def __enter__(self) -> RosClientMode:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    # ------------------------------------------------------------------ incoming
    def _sub(
        self,
        name: str,
        type_name: str,
        callback: Callable[[dict], None],
        on_invalid: Callable[[str], None],
    ) -> None:
        """Subscribe ``name`` on the remote: each message is validated against its type
        (as the built-in server validates a publish) before ``callback`` sees it."""
        import roslibpy

        if name in self.published_names:  # echo safety (also checked for the whole plan)
            raise ValueError(f"client mode publishes {name}: it cannot also take it as input")
        spec = self.registry.message(type_name)

        def checked(msg: dict) -> None:
            try:
                value = from_wire(self.registry, spec, msg)
            except MessageError as e:
                on_invalid(f"publish: {e}")  # the built-in server's status text
                return
            self.received[name] = self.received.get(name, 0) + 1
            try:
                callback(value)
            except (m.CommandError, ValueError) as e:
                self._log_refusal(f"{name}: {e}")

        # Commands keep the server's default queue (a state_command "enable" then "home" must
        # both arrive); streamed poses only need the latest.
        queue_length = 1 if name in self._streamed else 0
        topic = roslibpy.Topic(self.ros, name, type_name, queue_length=queue_length)
        topic.subscribe(checked)
        self._subscribed.append(topic)

    @property
    def _streamed(self) -> set[str]:
        return {f"/{mtm}/{s}" for mtm in self.config.mtms
                for s in ("measured_cp", "measured_js", "gripper/measured_js")}  # fmt: skip

    def _log_refusal(self, text: str) -> None:
        self.errors += 1
        _log.error("client mode: %s", text)

    def _refused(self, arm: str, refusal: Refusal) -> None:
        """A command for a simulated arm that moved nothing (maybe in the simulation's
        thread): on the remote's ``{ns}/<arm>/error`` unless the arm published it there."""
        self._log_refusal(refusal.text)
        if refusal.publish_error:
            self._outbox.put((self._arm_topic(arm, "error"), "std_msgs/String",
                              {"data": error_text(arm, refusal)}))  # fmt: skip

    def _on_event(self, source: str, event: str, payload: object) -> None:
        """The simulation's events (its thread): the arms' messages go to the remote."""
        if source in self.arms and event in EVENT_TOPICS:
            text = getattr(payload, "text", str(payload))
            self._outbox.put((self._arm_topic(source, event), EVENT_TOPICS[event],
                              {"data": text}))  # fmt: skip

    def _on_system(self, commands: tuple[str, ...]) -> None:
        """``{ns}/system/home`` …: the state commands on every arm, in order (dvrk.md 2.3)."""
        for arm in self.handle.snapshot().arms:
            for command in commands:
                self.handle.call(arm, "state_command", command).add_done_callback(
                    lambda f, a=arm, c=command: self._system_done(f"{a} {c}", f)
                )

    def _system_done(self, what: str, future) -> None:
        exc = future.exception()
        result = None if exc is not None else future.result()
        if exc is not None or not getattr(result, "accepted", True):
            self._log_refusal(f"system: {what}: {exc if exc is not None else result.message}")

    def _on_pose(self, mtm: str, msg: dict) -> None:
        T = m.pose_matrix(msg["pose"])
        self._remote_R[mtm] = T[:3, :3]
        if self.mode[mtm] == "device":
            self.handle.call(f"{mtm}/device", "push", T)

    def _on_joints(self, mtm: str, msg: dict) -> None:
        if self.mode[mtm] != "joints":
            return
        a = self.handle.snapshot().arms.get(mtm)
        if a is None or not (a.operating_state.is_homed and not a.operating_state.is_busy):
            return  # not ready yet (homing): do not flood its error channel
        q = m.ordered(msg["position"], msg["name"], a.measured_js.name, "position")
        self.handle.call(mtm, "servo_jp", q)

    def _on_gripper(self, mtm: str, msg: dict) -> None:
        if not msg["position"]:
            return
        angle = msg["position"][0]
        if self.mode[mtm] == "device":
            self.handle.call(f"{mtm}/device", "push", gripper=angle)
        elif mtm in self.handle.snapshot().arms:
            self.handle.call(f"{mtm}/gripper", "servo_jp", angle)

    def _on_button(self, button: str, msg: dict) -> None:
        buttons = list(msg["buttons"])
        if len(buttons) != 1 or buttons[0] not in (0, 1, 2):
            raise ValueError(f"{button}: a pedal Joy has buttons [0], [1] or [2], got {buttons}")
        if self.has_console:
            self.handle.call("console", "button", button, buttons)
        else:
            for mtm, mode in self.mode.items():
                if mode == "device":
                    self.handle.call(f"{mtm}/device", "push", buttons={button: buttons})
                    break

    # ------------------------------------------------------------------ outgoing
    def _publisher(self, name: str, type_name: str, latch: bool = False):
        import roslibpy

        if name not in self.published_names:  # echo safety: only planned names go out
            raise ValueError(f"client mode did not plan to publish {name}")
        topic = self._topics.get(name)
        if topic is None:
            topic = roslibpy.Topic(self.ros, name, type_name, latch=latch)
            topic.advertise()
            self._topics[name] = topic
        return topic

    def _send(self, name: str, type_name: str, msg: dict, latch: bool = False) -> None:
        import roslibpy

        self._publisher(name, type_name, latch).publish(roslibpy.Message(msg))

    def _run(self) -> None:
        c = self.config
        period = 1.0 / max(c.rate, c.wrench_rate, c.tf_rate)
        next_state = next_wrench = next_tf = time.monotonic()
        if self.robot is None:
            next_tf = float("inf")
        while not self._stop.wait(
            max(0.0, min(next_state, next_wrench, next_tf) - time.monotonic())
        ):
            now = time.monotonic()
            try:
                if not self.ros.is_connected or send_backlog() > MAX_BACKLOG:
                    # Streams are latest-wins: a period not sent is dropped, not queued
                    # behind the others (every send waits in one queue with every other
                    # client's of this process, its connects included).
                    self.skipped += 1
                    next_state = next_wrench = now + period
                    if self.robot is not None:
                        next_tf = now + period
                    continue
                snap = self.handle.snapshot()
                if now >= next_tf:
                    next_tf = max(next_tf + 1.0 / c.tf_rate, now - period)
                    self.robot.tick(snap, self._send)
                if now >= next_wrench:
                    next_wrench += 1.0 / c.wrench_rate
                    self._publish_wrenches(snap)
                if now >= next_state:
                    next_state += 1.0 / c.rate
                    self._publish_states(snap)
                self._publish_outbox()
            except Exception:
                self.errors += 1
                _log.exception("client mode: publishing failed")
            # never burst to catch up after a stall
            next_state = max(next_state, now - period)
            next_wrench = max(next_wrench, now - period)

    def _publish_states(self, snap: Snapshot) -> None:
        import roslibpy

        d, stamp = self.dialect, time.time()
        for name in self.arms:
            a = snap.arms.get(name)
            if a is None:
                continue
            base = f"{self.prefix}/{name}"
            msgs = [
                ("measured_js", "sensor_msgs/JointState", m.joint_state(d, a.measured_js, stamp)),
                ("measured_cp", "geometry_msgs/PoseStamped",
                 m.pose_stamped(d, a.measured_cp, stamp)),
                ("setpoint_cp", "geometry_msgs/PoseStamped",
                 m.pose_stamped(d, a.setpoint_cp, stamp)),
            ]  # fmt: skip
            if a.jaw_measured_js is not None:
                msgs.append(("jaw/measured_js", "sensor_msgs/JointState",
                             m.joint_state(d, a.jaw_measured_js, stamp)))  # fmt: skip
            s = a.operating_state
            key = (s.state, s.is_homed, s.is_busy)
            if self._last_state.get(name) != key:
                self._last_state[name] = key
                msgs.append(("operating_state", "crtk_msgs/OperatingState",
                             m.operating_state(d, s, stamp)))  # fmt: skip
            for suffix, type_name, msg in msgs:
                # operating_state goes out on change only: latched for late subscribers
                latch = suffix == "operating_state"
                topic = self._publisher(f"{base}/{suffix}", type_name, latch)
                topic.publish(roslibpy.Message(msg))

    def _publish_outbox(self) -> None:
        """Events and refusals, published from this thread only (one owner of the topics)."""
        import roslibpy

        while True:
            try:
                name, type_name, msg = self._outbox.get_nowait()
            except queue.Empty:
                return
            self._publisher(name, type_name).publish(roslibpy.Message(msg))

    def _publish_wrenches(self, snap: Snapshot) -> None:
        import roslibpy

        for mtm, w in self.wrench_source(snap).items():
            if mtm not in self.config.mtms:
                continue
            w = np.asarray(w, dtype=float)
            on = bool(np.any(w != 0.0)) and bool(np.all(np.isfinite(w)))
            if not on and not self._wrench_on.get(mtm, False):
                continue  # idle: leave the real MTM's mode alone
            self._wrench_on[mtm] = on
            R = self._remote_R.get(mtm)
            if R is None:
                continue  # no pose yet: cannot express the wrench in the body frame
            if not on:
                w = np.zeros(6)
            body = np.concatenate([R.T @ w[:3], R.T @ w[3:]])  # HRSV axes → handle frame
            msg = m.wrench_stamped(self.dialect, body, mtm, time.time())
            self._publisher(f"/{mtm}/body/servo_cf", "geometry_msgs/WrenchStamped").publish(
                roslibpy.Message(msg)
            )
