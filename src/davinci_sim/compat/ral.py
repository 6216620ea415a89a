"""``crtk.ral``: the ROS abstraction layer of crtk_python, over a rosbridge client.

A dVRK script makes one ``ral`` (``crtk.ral('node_name')``) and hands it to the arms, which
make children for their namespaces (``PSM1``, ``PSM1/jaw`` …). Here every ``ral`` of the
process shares one :class:`~davinci_sim.compat.transport.RosbridgeClient`: the one
``davinci-sim run`` installs with :func:`set_client` (in-process or ``--connect``), or else
one connected to ``$DAVINCI_SIM_CONNECT`` (default ``ws://127.0.0.1:9090``, what
``davinci-sim serve`` listens on) when the first ``ral`` is made.

Messages are rosbridge JSON objects. Publishers take a dict, a :class:`Message` or a message
object (``std_msgs.msg.Bool(data=True)``: ours, :mod:`davinci_sim.compat.msgs`, or a ROS
installation's). A subscriber made with a message class (``std_msgs.msg.Bool``, as the dVRK
scripts do) gives its callback objects of that class; one made with a type name gives
:class:`Message` wrappers, so that ``msg.data``, ``msg.position``, ``msg.header.stamp`` read
as on a ROS message either way. Times are float seconds of the wall clock (``now``,
``to_sec``), the clock the simulator stamps its messages with by default.

With simulated time (ROS's ``use_sim_time``: ``$DAVINCI_SIM_USE_SIM_TIME=1``, ``davinci-sim
run --sim-time``, a ``use_sim_time:=true`` ROS argument, or ``ral(..., use_sim_time=True)``),
``now`` and ``create_rate`` follow the server's ``/clock`` instead: a script's 100 Hz loop
then sends 100 goals per simulated second whatever the machine's load, as a ROS node does
against Gazebo. (On the wall clock, a simulation running below real time takes a stream's
goals closer together in its own time: faster motions, and on a loaded machine bursts.)
"""

from __future__ import annotations

import logging
import os
import threading
import time
import weakref
from collections.abc import Callable
from typing import Any

from davinci_sim.compat import msgs
from davinci_sim.compat.ral_clock import (  # noqa: F401 (ENV_SIM_TIME, Rate: crtk.ral's API)
    ENV_SIM_TIME,
    Rate,
    SimClock,
    sim_clock,
    sim_time_requested,
    stamp_seconds,
)
from davinci_sim.compat.transport import RosbridgeClient, TransportError

_log = logging.getLogger("davinci_sim.compat")

DEFAULT_URL = "ws://127.0.0.1:9090"
FIRST_DATA_WAIT = 0.2
"""s: how long ``check_connections`` waits for subscribers' first messages once connected
(the dVRK's state topics are 100 Hz: their first message comes within 10 ms)."""
ENV_URL = "DAVINCI_SIM_CONNECT"

_client: RosbridgeClient | None = None
_client_lock = threading.Lock()


class _Context:
    """What rclpy's context is to its nodes: shut down once, for every ``ral`` of one client
    (by ``ral.shutdown()`` or when the connection closes), with its ``on_shutdown``
    callbacks."""

    def __init__(self) -> None:
        self.down = threading.Event()
        self.callbacks: list[Callable[[], None]] = []
        self._lock = threading.Lock()

    def shutdown(self) -> None:
        with self._lock:
            if self.down.is_set():
                return
            self.down.set()
        for callback in list(self.callbacks):
            try:
                callback()
            except Exception:
                _log.exception("on_shutdown callback failed")


_contexts: weakref.WeakKeyDictionary[RosbridgeClient, _Context] = weakref.WeakKeyDictionary()


def _context(client_: RosbridgeClient) -> _Context:
    with _client_lock:
        context = _contexts.get(client_)
        if context is None:
            context = _contexts[client_] = _Context()
            client_.close_callbacks.append(context.shutdown)
        return context


def set_client(client: RosbridgeClient | None) -> None:
    """The client every ``ral`` of this process uses from now on (None: forget it)."""
    global _client
    with _client_lock:
        _client = client


def client() -> RosbridgeClient:
    """The process's client; connects to ``$DAVINCI_SIM_CONNECT`` on first use."""
    global _client
    with _client_lock:
        if _client is None:
            from davinci_sim.compat.transport import WebSocketConnection

            url = os.environ.get(ENV_URL, DEFAULT_URL)
            _client = RosbridgeClient(WebSocketConnection(url), description=url)
        return _client


class Message:
    """A rosbridge message (a dict) read with attributes, as a ROS message: nested objects
    are :class:`Message` too; ``dict(msg)`` or ``msg.to_dict()`` gives the dict back."""

    __slots__ = ("_d",)

    def __init__(self, d: dict | None = None, **fields: Any) -> None:
        object.__setattr__(self, "_d", dict(d or {}, **fields))

    def __getattr__(self, name: str) -> Any:
        try:
            value = self._d[name]
        except KeyError:
            raise AttributeError(name) from None
        return Message(value) if isinstance(value, dict) else value

    def __setattr__(self, name: str, value: Any) -> None:
        self._d[name] = value.to_dict() if isinstance(value, Message) else value

    def to_dict(self) -> dict:
        return self._d

    def keys(self):
        return self._d.keys()

    def __getitem__(self, key: str) -> Any:
        return self._d[key]

    def __repr__(self) -> str:
        return f"Message({self._d!r})"


def to_dict(msg: Any, what: str = "a message", ros_version: int = 2) -> dict:
    """``msg`` (dict, :class:`Message` or message object) as a rosbridge JSON object, its
    times in ``ros_version``'s spelling.

    Raises:
        TypeError: ``msg`` is none of those.
    """
    if isinstance(msg, Message):
        return msg.to_dict()
    if isinstance(msg, dict) or msgs.is_message(msg):
        return msgs.to_wire(msg, ros_version)
    raise TypeError(f"{what} must be a ROS message object or a dict, got {type(msg).__name__}")


def stamp_of(msg: Any) -> float:
    """The header stamp of ``msg`` (dict, :class:`Message` or message object) in s; 0
    without one."""
    d = msg.to_dict() if isinstance(msg, Message) else msg
    if msgs.is_message(d):
        d = msgs.to_wire(d)
    if not isinstance(d, dict):
        return float(d) if isinstance(d, int | float) else 0.0
    stamp = d.get("header", {}).get("stamp", d.get("stamp")) if "header" in d else d.get("stamp", d)
    if not isinstance(stamp, dict):
        return 0.0
    return stamp_seconds(stamp)


class Publisher:
    def __init__(self, topic: str, type_name: str, client_: RosbridgeClient) -> None:
        self.topic_name, self.type = topic, type_name
        self._client = client_

    def publish(self, msg: Any) -> None:
        """Send ``msg``: a message object (``std_msgs.msg.Bool(data=True)``), a dict or a
        :class:`Message`."""
        version = self._client.ros_version() if msgs.is_message(msg) else 2  # times' spelling
        d = to_dict(msg, f"what is published on {self.topic_name}", version)
        self._client.publish(self.topic_name, self.type, d)


class Subscriber:
    def __init__(self, topic: str, type_name: str) -> None:
        self.topic_name, self.type = topic, type_name
        self.received = threading.Event()
        """Set by the first message."""


class ServiceClient:
    """Called with a request (dict or :class:`Message`), returns the response as a
    :class:`Message` (as ``client.call(request)`` of rclpy)."""

    def __init__(self, name: str, type_name: str, client_: RosbridgeClient) -> None:
        self.srv_name, self.type = name, type_name
        self._client = client_

    def call(self, request: Any, timeout: float = 10.0) -> Message:
        d = to_dict(request, f"a request of {self.srv_name}")
        return Message(self._client.call_service(self.srv_name, d, type_name=self.type,
                                                 timeout=timeout))  # fmt: skip

    __call__ = call


class ral:  # noqa: N801 (crtk's name)
    """The ROS abstraction layer (see the module docstring)."""

    @staticmethod
    def ros_version() -> int:
        return 2

    @staticmethod
    def parse_argv(argv: list[str]) -> list[str]:
        """``argv`` without ROS arguments (``--ros-args … [--]``, ROS 1 ``name:=value``)."""
        out: list[str] = []
        in_ros = False
        for arg in argv:
            if arg == "--ros-args":
                in_ros = True
            elif in_ros and arg == "--":
                in_ros = False
            elif not in_ros and ":=" not in arg:
                out.append(arg)
        return out

    def __init__(self, node_name: str, namespace: str = "", node: RosbridgeClient | None = None,
                 use_sim_time: bool | None = None):  # fmt: skip
        """``use_sim_time``: None = as :func:`sim_time_requested` says."""
        self._node_name = node_name
        self._namespace = namespace.strip("/")
        self._children: dict[str, ral] = {}
        self._publishers: list[Publisher] = []
        self._subscribers: list[Subscriber] = []
        self._client = node if node is not None else client()
        self._context = _context(self._client)
        if use_sim_time is None:
            use_sim_time = sim_time_requested()
        self._clock: SimClock | None = sim_clock(self._client) if use_sim_time else None

    # ------------------------------------------------------------ names
    def node_name(self) -> str:
        return self._node_name

    def namespace(self) -> str:
        return self._namespace

    def _add_namespace_to(self, name: str) -> str:
        name = name.strip("/")
        return "/" + "/".join(p for p in (self._namespace, name) if p)

    def create_child(self, child_namespace: str) -> ral:
        if child_namespace in self._children:
            raise RuntimeError(f'ral object already has child "{child_namespace}"!')
        child = ral(self._node_name, self._add_namespace_to(child_namespace), self._client,
                    use_sim_time=self._clock is not None)  # fmt: skip
        self._children[child_namespace] = child
        return child

    # ------------------------------------------------------------ time
    def now(self) -> float:
        """Wall-clock time, s; with simulated time, the server's ``/clock`` (s)."""
        return time.time() if self._clock is None else self._clock.now()

    def get_timestamp(self, t: Any) -> float:
        """The stamp of a message (or a time) in s."""
        return stamp_of(t)

    def to_sec(self, t: Any) -> float:
        return self.get_timestamp(t)

    def create_duration(self, d: float) -> float:
        return float(d)

    def create_rate(self, rate_hz: float) -> Rate:
        return Rate(rate_hz, self._clock, self.is_shutdown)

    def create_time(self) -> float:
        return 0.0

    def set_timestamp(self, msg: Any) -> Any:
        """Stamp ``msg``'s header with :meth:`now`, in the server's dialect (ROS 1:
        ``secs``/``nsecs``, ROS 2: ``sec``/``nanosec``)."""
        t = self.now()
        sec, nsec = int(t), int((t - int(t)) * 1e9)
        if self._client.ros_version() == 1:
            stamp = {"secs": sec, "nsecs": nsec}
        else:
            stamp = {"sec": sec, "nanosec": nsec}
        if isinstance(msg, Message):
            msg.to_dict()["header"] = {"stamp": stamp, "frame_id": ""}
        elif isinstance(msg, dict):
            msg["header"] = {"stamp": stamp, "frame_id": ""}
        elif msgs.is_message(getattr(msg, "header", None)):
            msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nsec
        return msg

    # ------------------------------------------------------------ life cycle
    def spin(self) -> None:
        """Nothing to start: messages arrive on the connection's reader thread."""

    def shutdown(self) -> None:
        self._context.shutdown()

    def spin_and_execute(self, function: Callable, *arguments: Any) -> None:
        self.spin()
        try:
            function(*arguments)
        except KeyboardInterrupt:
            pass
        self.shutdown()

    def on_shutdown(self, callback: Callable[[], None]) -> None:
        self._context.callbacks.append(callback)

    def is_shutdown(self) -> bool:
        return self._context.down.is_set() or self._client.closed.is_set()

    # ------------------------------------------------------------ topics
    def publisher(self, topic: str, msg_type: str, queue_size: int = 10, latch: bool = False,
                  *args: Any, **kwargs: Any) -> Publisher:  # fmt: skip
        pub = Publisher(self._add_namespace_to(topic), _type_name(msg_type), self._client)
        self._publishers.append(pub)
        return pub

    def subscriber(self, topic: str, msg_type: str, callback: Callable, queue_size: int = 10,
                   latch: bool = False, *args: Any, **kwargs: Any) -> Subscriber:  # fmt: skip
        sub = Subscriber(self._add_namespace_to(topic), _type_name(msg_type))
        receive = _receiver(msg_type, callback)

        def on_message(d: dict) -> None:
            sub.received.set()
            receive(d)

        self._client.subscribe(sub.topic_name, sub.type, on_message,
                               queue_length=int(queue_size))  # fmt: skip
        self._subscribers.append(sub)
        return sub

    def service_client(self, name: str, srv_type: str) -> ServiceClient:
        return ServiceClient(self._add_namespace_to(name), _type_name(srv_type), self._client)

    def get_topic_name(self, pubsub: Publisher | Subscriber) -> str:
        return pubsub.topic_name

    # ------------------------------------------------------------ connections
    def check_connections(self, timeout_seconds: float = 5.0, check_children: bool = True):
        """Wait up to ``timeout_seconds`` until every publisher of this ``ral`` (and of its
        children) has a subscriber and every subscriber a publisher, as the server's
        ``/rosapi`` reports them; then up to :data:`FIRST_DATA_WAIT` more for every
        subscriber's first message (on ROS, discovery outlasts a 100 Hz topic's first
        message: scripts read ``measured_js()`` right after this, even before a move).

        Topics dvrk_python uses that the simulator does not serve
        (:data:`~davinci_sim.compat.dvrk_api.NOT_SIMULATED`) are not waited for.

        Raises:
            TimeoutError: some are still unconnected (named in the message).
        """
        if timeout_seconds == 0.0:
            return
        from davinci_sim.compat.dvrk_api import NOT_SIMULATED

        end = time.monotonic() + timeout_seconds
        pubs, subs = self._all(check_children)
        pubs = [p for p in pubs if p.topic_name.rsplit("/", 1)[-1] not in NOT_SIMULATED]
        unconnected_pubs, unconnected_subs = pubs, subs
        while True:
            unconnected_pubs = [p for p in unconnected_pubs if not self._has(p, "subscribers")]
            unconnected_subs = [s for s in unconnected_subs if not self._has(s, "publishers")]
            if not unconnected_pubs and not unconnected_subs:
                first_data = min(end, time.monotonic() + FIRST_DATA_WAIT)
                for sub in subs:  # event topics (pedals) may send nothing: not an error
                    sub.received.wait(max(0.0, first_data - time.monotonic()))
                return
            if time.monotonic() >= end or self.is_shutdown():
                break
            time.sleep(0.01)
        names = ", ".join
        raise TimeoutError(
            "Timed out waiting for publisher/subscriber connections to establish\n"
            f"    Publishers:  {len(pubs) - len(unconnected_pubs)} connected, "
            f"{len(unconnected_pubs)} not connected\n"
            f"                 not connected: [{names(p.topic_name for p in unconnected_pubs)}]\n\n"
            f"    Subscribers: {len(subs) - len(unconnected_subs)} connected, "
            f"{len(unconnected_subs)} not connected\n"
            f"                 not connected: [{names(s.topic_name for s in unconnected_subs)}]\n"
        )

    def _all(self, children: bool) -> tuple[list[Publisher], list[Subscriber]]:
        pubs, subs = list(self._publishers), list(self._subscribers)
        if children:
            for child in self._children.values():
                p, s = child._all(True)
                pubs += p
                subs += s
        return pubs, subs

    def _has(self, pubsub: Publisher | Subscriber, which: str) -> bool:
        try:
            values = self._client.call_service(f"/rosapi/{which}", {"topic": pubsub.topic_name},
                                               timeout=2.0)  # fmt: skip
        except (RuntimeError, TimeoutError, TransportError):
            return True  # a server without rosapi: nothing to check against
        return bool(values.get(which))


def _receiver(msg_type: Any, callback: Callable) -> Callable[[dict], None]:
    """What a subscriber calls with each rosbridge message: ``callback`` with an object of
    ``msg_type`` if it is a message class, else with a :class:`Message`."""
    if isinstance(msg_type, type) and issubclass(msg_type, msgs.MessageBase):
        return lambda d: callback(msgs.from_wire(msg_type._type, d))
    if isinstance(msg_type, type) and msgs.is_message_class(msg_type):  # a ROS installation's
        return lambda d: callback(msgs.fill(msg_type(), d))
    return lambda d: callback(Message(d))


def _type_name(msg_type: Any) -> str:
    """A rosbridge type name from a string, or from a class with ROS's ``_type`` (ROS 1) or
    module path (ROS 2), for scripts that pass message classes."""
    if isinstance(msg_type, str):
        return msg_type
    t = getattr(msg_type, "_type", None)
    if isinstance(t, str):
        return t
    module = getattr(msg_type, "__module__", "")
    return f"{module.split('.')[0]}/{getattr(msg_type, '__name__', '')}"
