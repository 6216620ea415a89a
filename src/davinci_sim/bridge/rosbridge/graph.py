"""The bridge's ROS graph: topics, services and actions, who provides and who uses them.

Bookkeeping only (no I/O): :class:`~davinci_sim.bridge.rosbridge.core.Bridge` owns these objects and
runs everything in its event loop's thread.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from davinci_sim.bridge.rosbridge import codec
from davinci_sim.bridge.rosbridge.convert import to_cbor_value
from davinci_sim.bridge.rosbridge.protocol import Id, PublishOut, to_wire
from davinci_sim.bridge.rosbridge.types import ActionSpec, MsgSpec, SrvSpec, TypeRegistry

if TYPE_CHECKING:
    from davinci_sim.bridge.rosbridge.session import Session

#: An internal subscriber: ``callback(msg, session_or_None)``.
Listener = Callable[[dict, "Session | None"], None]
#: An internal service: ``await handler(request, session_or_None) -> response values``.
ServiceHandler = Callable[[dict, "Session | None"], Awaitable[dict]]
#: An internal action: ``await handler(goal, send_feedback) -> result values``.
ActionHandler = Callable[[dict, Callable[[dict], None]], Awaitable[dict]]

COMPRESSIONS = ("none", "png", "cbor", "cbor-raw")


class OutMessage:
    """One published message, encoded at most once per encoding whatever the subscriber
    count (rosbridge.md §6.3)."""

    __slots__ = ("topic", "msg", "_spec", "_registry", "_json", "_cbor", "_png")

    def __init__(self, topic: str, msg: dict, spec: MsgSpec, registry: TypeRegistry) -> None:
        self.topic = topic
        self.msg = msg
        self._spec = spec
        self._registry = registry
        self._json: bytes | None = None
        self._cbor: bytes | None = None
        self._png: bytes | None = None

    def json(self) -> bytes:
        """The ``publish`` op as UTF-8 JSON (ASCII only)."""
        if self._json is None:
            self._json = codec.dumps(to_wire(PublishOut(self.topic, self.msg))).encode("ascii")
        return self._json

    def cbor(self) -> bytes:
        if self._cbor is None:
            msg = to_cbor_value(self._registry, self._spec, self.msg)
            self._cbor = codec.cbor_frame({"op": "publish", "topic": self.topic, "msg": msg})
        return self._cbor

    def png(self) -> bytes:
        if self._png is None:
            self._png = codec.png_op(self.json().decode("ascii")).encode("ascii")
        return self._png


@dataclass(eq=False)
class Subscription:
    """One client's subscription to one topic, merged over its subscribe ids (rosbridge.md
    §1.3: throttle = min, queue_length = min, fragment_size = min, compression by priority)."""

    topic: Topic
    session: Session
    ids: dict[Any, dict] = field(default_factory=dict)
    throttle: float = 0.0
    """Seconds between two messages (0: no throttle)."""
    queue_length: int = 0
    compression: str = "none"
    fragment_size: int | None = None
    queue: deque = field(default_factory=deque)
    dropped: int = 0
    last_accept: float = -1e18
    next_send: float = 0.0
    in_ready: bool = False
    closed: bool = False

    def merge(self, default_queue: int) -> None:
        params = list(self.ids.values())
        throttles = [p["throttle_rate"] for p in params]
        queues = [p["queue_length"] for p in params]
        frags = [p["fragment_size"] for p in params if p["fragment_size"]]
        comps = [p["compression"] for p in params]
        self.throttle = min(throttles) / 1000.0 if throttles else 0.0
        self.queue_length = min(queues) if queues else 0
        self.fragment_size = min(frags) if frags else None
        self.compression = next((c for c in reversed(COMPRESSIONS) if c in comps), "none")
        maxlen = self.queue_length if self.queue_length > 0 else default_queue
        if self.queue.maxlen != maxlen:
            self.queue = deque(self.queue, maxlen=maxlen)


@dataclass(eq=False)
class Topic:
    """A topic of the graph.

    ``owner`` names the internal node that fixed its type (e.g. ``/davinci_sim``); such a
    topic keeps its type and survives its clients. Other topics exist while a client
    advertises or subscribes them.
    """

    name: str
    type: str
    spec: MsgSpec
    owner: str | None = None
    latch: bool = False
    last: OutMessage | None = None
    publishers: dict[Any, set] = field(default_factory=dict)
    """Publisher key (node name or session) → its advertise ids."""
    subscriptions: dict[Session, Subscription] = field(default_factory=dict)
    listeners: list[tuple[str, Listener]] = field(default_factory=list)
    seq: int = 0
    published: int = 0

    @property
    def has_subscribers(self) -> bool:
        return bool(self.subscriptions) or bool(self.listeners)

    @property
    def has_client_subscribers(self) -> bool:
        return bool(self.subscriptions)

    def next_seq(self) -> int:
        """The next ROS 1 ``Header.seq`` of this topic."""
        self.seq += 1
        return self.seq

    def unused(self) -> bool:
        return self.owner is None and not self.publishers and not self.has_subscribers


@dataclass(eq=False)
class ServiceEntry:
    """A service: provided by an internal ``handler`` or by a client ``provider``."""

    name: str
    type: str
    spec: SrvSpec
    node: str
    handler: ServiceHandler | None = None
    provider: Session | None = None


@dataclass(eq=False)
class ActionEntry:
    name: str
    type: str
    spec: ActionSpec
    node: str
    handler: ActionHandler | None = None
    provider: Session | None = None


@dataclass(eq=False)
class GoalRoute:
    """A goal in flight: who asked (``caller``, ``caller_id``) and, for a client-provided
    action, the id the provider knows it by."""

    action: str
    caller: Session
    caller_id: Id
    feedback: bool
    provider_id: str | None = None
    task: Any = None
