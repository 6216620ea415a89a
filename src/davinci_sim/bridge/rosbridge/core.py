"""The bridge: the ROS graph, routing between clients and internal nodes, rosbridge ops.

Everything here runs in the server's event loop thread. Internal nodes (the dVRK API,
rosapi, the endoscope) use :meth:`Bridge.advertise`, :meth:`Bridge.listen`,
:meth:`Bridge.publish`, :meth:`Bridge.provide_service` and :meth:`Bridge.provide_action`;
client ops arrive through :meth:`Bridge.handle_op` (semantics of rosbridge_suite, rosbridge.md
§1.3–1.5, with the errors reported instead of only logged).

Size: one class, because every op reads and changes the same routing tables (topics,
subscriptions, services, action goals and their owners); split by op, each part would reach
into the others' state.
"""

from __future__ import annotations

import asyncio
import itertools
import logging
import re
import time
from collections.abc import Callable
from typing import Any

from davinci_sim.bridge.rosbridge.config import BridgeConfig
from davinci_sim.bridge.rosbridge.convert import MessageError, from_wire
from davinci_sim.bridge.rosbridge.dialect import TypeNameError, dialect, split_type
from davinci_sim.bridge.rosbridge.graph import (
    COMPRESSIONS,
    ActionEntry,
    ActionHandler,
    GoalRoute,
    Listener,
    OutMessage,
    ServiceEntry,
    ServiceHandler,
    Subscription,
    Topic,
)
from davinci_sim.bridge.rosbridge.protocol import (
    GOAL_STATUS,
    ActionFeedback,
    ActionFeedbackOut,
    ActionResult,
    ActionResultOut,
    Advertise,
    AdvertiseAction,
    AdvertiseService,
    CallService,
    CallServiceOut,
    CancelActionGoal,
    CancelActionGoalOut,
    Publish,
    SendActionGoal,
    SendActionGoalOut,
    ServiceResponse,
    ServiceResponseOut,
    Subscribe,
    Unadvertise,
    UnadvertiseAction,
    UnadvertiseService,
    Unsubscribe,
)
from davinci_sim.bridge.rosbridge.session import Session
from davinci_sim.bridge.rosbridge.types import MsgSpec, TypeRegistry, UnknownTypeError

_log = logging.getLogger("davinci_sim.bridge")

BRIDGE_NODE = "/rosbridge_websocket"
_NAME = re.compile(r"^/?[A-Za-z0-9_~][A-Za-z0-9_/~]*$")


class ServiceFailure(Exception):
    """Raised by a service handler: the caller gets ``result: false`` with this text."""


class BridgeError(ValueError):
    """A client request the bridge refuses; reported to that client."""


def clean_name(name: str, what: str = "topic") -> str:
    """``/name`` from ``name`` or ``/name``.

    Raises:
        BridgeError: for an empty or malformed ROS name.
    """
    if not isinstance(name, str) or not _NAME.match(name) or "//" in name:
        raise BridgeError(f"invalid {what} name {name!r}")
    return name if name.startswith("/") else "/" + name


class Bridge:
    """The graph and the routing of one server.

    Args:
        config: the server's options.
        registry: message definitions (default: the built-in ones for the configured dialect).
        clock: ROS time in seconds (default: wall clock).
    """

    def __init__(
        self,
        config: BridgeConfig,
        registry: TypeRegistry | None = None,
        clock: Callable[[], float] = time.time,
    ) -> None:
        self.config = config
        self.dialect = dialect(config.ros_version)
        self.registry = registry or TypeRegistry(self.dialect)
        self.clock = clock
        self.topics: dict[str, Topic] = {}
        self.services: dict[str, ServiceEntry] = {}
        self.actions: dict[str, ActionEntry] = {}
        self.sessions: set[Session] = set()
        self.params: dict[str, str] = {}
        self.nodes: set[str] = {BRIDGE_NODE}
        self._pending_calls: dict[str, tuple[asyncio.Future, Session]] = {}
        self._goals: dict[Any, GoalRoute] = {}
        self._counter = itertools.count(1)
        self._rosout: Topic | None = None
        self._in_rosout = False

    # ================================================================ internal API
    def now(self) -> float:
        """ROS time, s."""
        return self.clock()

    def _topic_for(self, name: str, type_name: str, owner: str | None) -> Topic:
        spec = self.registry.message(type_name)
        topic = self.topics.get(name)
        if topic is None:
            topic = Topic(name, spec.name, spec, owner=owner)
            self.topics[name] = topic
        elif topic.type != spec.name:
            who = f"the simulator ({topic.owner})" if topic.owner else "another client"
            raise BridgeError(
                f"topic {name} has type {self.registry.wire_name(topic.type)} "
                f"(set by {who}); it cannot be used as {type_name}"
            )
        elif owner and topic.owner is None:
            topic.owner = owner
        return topic

    def advertise(self, name: str, type_name: str, *, node: str, latch: bool = False) -> Topic:
        """A topic an internal node publishes; its type is fixed from now on."""
        self.nodes.add(node)
        topic = self._topic_for(clean_name(name), type_name, node)
        topic.latch = topic.latch or latch
        topic.publishers.setdefault(node, set())
        return topic

    def listen(self, name: str, type_name: str, callback: Listener, *, node: str) -> Topic:
        """Call ``callback(msg, session)`` for every valid message published on a topic."""
        self.nodes.add(node)
        topic = self._topic_for(clean_name(name), type_name, node)
        topic.listeners.append((node, callback))
        return topic

    def publish(self, topic: Topic, msg: dict, source: Session | None = None) -> None:
        """Send ``msg`` to every subscriber of ``topic`` (once per client)."""
        out = OutMessage(topic.name, msg, topic.spec, self.registry)
        topic.published += 1
        if topic.latch:
            topic.last = out
        for session, sub in topic.subscriptions.items():
            session.enqueue(sub, out)
        for node, callback in topic.listeners:
            try:
                callback(msg, source)
            except Exception:
                _log.exception("listener of %s in %s failed", topic.name, node)

    def provide_service(self, name: str, type_name: str, handler: ServiceHandler, *, node: str):
        """An internal service."""
        self.nodes.add(node)
        name = clean_name(name, "service")
        spec = self.registry.service(type_name)
        self.services[name] = ServiceEntry(name, spec.name, spec, node, handler=handler)

    def provide_action(self, name: str, type_name: str, handler: ActionHandler, *, node: str):
        """An internal ROS 2 action server."""
        self.nodes.add(node)
        name = clean_name(name, "action")
        spec = self.registry.action(type_name)
        self.actions[name] = ActionEntry(name, spec.name, spec, node, handler=handler)

    def remove_node(self, node: str) -> None:
        """Forget everything an internal node provided (when it detaches)."""
        for topic in list(self.topics.values()):
            topic.publishers.pop(node, None)
            topic.listeners = [(n, cb) for n, cb in topic.listeners if n != node]
            if topic.owner == node:
                topic.owner = None
            self._maybe_drop(topic)
        for name in [n for n, s in self.services.items() if s.node == node and s.handler]:
            del self.services[name]
        for name in [n for n, a in self.actions.items() if a.node == node and a.handler]:
            del self.actions[name]
        self.nodes.discard(node)

    def rosout(self, level: str, text: str) -> None:
        """Put a line on ``/rosout`` (if anyone listens)."""
        if self._rosout is None or not self._rosout.has_subscribers or self._in_rosout:
            return
        self._in_rosout = True
        try:
            d = self.dialect
            if d.ros_version == 1:
                code = {"info": 2, "warning": 4, "error": 8}.get(level, 2)
                msg = {
                    "header": d.header(self.now(), "", self._rosout.next_seq()),
                    "level": code,
                    "name": BRIDGE_NODE,
                    "msg": text,
                    "file": "",
                    "function": "",
                    "line": 0,
                    "topics": [],
                }
            else:
                code = {"info": 20, "warning": 30, "error": 40}.get(level, 20)
                msg = {
                    "stamp": d.stamp(self.now()),
                    "level": code,
                    "name": BRIDGE_NODE.strip("/"),
                    "msg": text,
                    "file": "",
                    "function": "",
                    "line": 0,
                }
            self.publish(self._rosout, msg)
        finally:
            self._in_rosout = False

    def setup_rosout(self) -> None:
        log_type = "rosgraph_msgs/Log" if self.dialect.ros_version == 1 else "rcl_interfaces/Log"
        self._rosout = self.advertise("/rosout", log_type, node=BRIDGE_NODE)

    # ================================================================ sessions
    def add_session(self, session: Session) -> None:
        self.sessions.add(session)
        _log.info("%s connected", session.name)

    def remove_session(self, session: Session) -> None:
        """Forget everything a client had: subscriptions, publishers, services, actions."""
        self.sessions.discard(session)
        for name in list(session.subscriptions):
            self._drop_subscription(session, name)
        for name in list(session.advertised):
            topic = self.topics.get(name)
            if topic is not None:
                topic.publishers.pop(session, None)
                self._maybe_drop(topic)
        session.advertised.clear()
        for name in list(session.services):
            entry = self.services.get(name)
            if entry is not None and entry.provider is session:
                del self.services[name]
        for future, provider in list(self._pending_calls.values()):
            if provider is session and not future.done():
                future.set_exception(ServiceFailure("the service provider disconnected"))
        for name in list(session.actions):
            entry = self.actions.get(name)
            if entry is not None and entry.provider is session:
                del self.actions[name]
                for key, route in list(self._goals.items()):
                    if route.action == name and route.provider_id is not None:
                        self._finish_goal(key, "the action server disconnected", "ABORTED", False)
        for key, route in list(self._goals.items()):
            if route.caller is session:
                if route.task is not None:
                    route.task.cancel()
                self._goals.pop(key, None)
        _log.info("%s disconnected", session.name)

    def _maybe_drop(self, topic: Topic) -> None:
        if topic.unused() and self.topics.get(topic.name) is topic:
            del self.topics[topic.name]

    def _drop_subscription(self, session: Session, name: str) -> None:
        sub = session.subscriptions.pop(name, None)
        if sub is None:
            return
        sub.closed = True
        sub.queue.clear()
        topic = self.topics.get(name)
        if topic is not None:
            topic.subscriptions.pop(session, None)
            self._maybe_drop(topic)

    # ================================================================ client ops
    def handle_op(self, session: Session, op: Any) -> None:
        handler = getattr(self, f"_op_{op.op}")
        try:
            handler(session, op)
        except (BridgeError, MessageError, UnknownTypeError, TypeNameError) as e:
            session.report("error", f"{op.op}: {e}", getattr(op, "id", None))

    def _op_advertise(self, session: Session, op: Advertise) -> None:
        name = clean_name(op.topic)
        topic = self._topic_for(name, op.type, None)
        topic.publishers.setdefault(session, set()).add(op.id)
        session.advertised.setdefault(name, set()).add(op.id)
        if op.latch:
            topic.latch = True

    def _op_unadvertise(self, session: Session, op: Unadvertise) -> None:
        name = clean_name(op.topic)
        ids = session.advertised.get(name)
        if ids is None:
            raise BridgeError(f"topic {name} is not advertised by this client")
        if op.id is not None:
            ids.discard(op.id)
        if op.id is None or not ids:
            session.advertised.pop(name, None)
            topic = self.topics.get(name)
            if topic is not None:
                topic.publishers.pop(session, None)
                self._maybe_drop(topic)

    def _op_publish(self, session: Session, op: Publish) -> None:
        name = clean_name(op.topic)
        topic = self.topics.get(name)
        if topic is None:
            raise BridgeError(
                f"cannot infer the type of {name}: advertise it first (with its type)"
            )
        msg = from_wire(self.registry, topic.spec, op.msg)
        if session not in topic.publishers:  # implicit advertise (rosbridge.md §1.3)
            topic.publishers[session] = {None}
            session.advertised.setdefault(name, set()).add(None)
        if op.latch:
            topic.latch = True
        self.publish(topic, msg, session)

    def _op_subscribe(self, session: Session, op: Subscribe) -> None:
        name = clean_name(op.topic)
        if op.compression is not None and op.compression not in COMPRESSIONS:
            raise BridgeError(f"unknown compression {op.compression!r}; use one of {COMPRESSIONS}")
        if op.throttle_rate < 0 or op.queue_length < 0:
            raise BridgeError("throttle_rate and queue_length must be >= 0")
        if op.type:
            topic = self._topic_for(name, op.type, None)
        else:
            topic = self.topics.get(name)
            if topic is None:
                raise BridgeError(f"cannot subscribe to unknown topic {name} without a type")
        compression = op.compression or "none"
        if compression == "cbor-raw":
            session.report(
                "warning",
                "subscribe: cbor-raw (ROS-serialized bytes) is not supported; sending cbor",
                op.id,
            )
            compression = "cbor"
        sub = session.subscriptions.get(name)
        if sub is None:
            sub = Subscription(topic, session)
            session.subscriptions[name] = sub
            topic.subscriptions[session] = sub
        sub.ids[op.id] = {
            "throttle_rate": op.throttle_rate,
            "queue_length": op.queue_length,
            "fragment_size": op.fragment_size,
            "compression": compression,
        }
        sub.merge(self.config.send_queue_length)
        if topic.last is not None:
            session.enqueue(sub, topic.last)

    def _op_unsubscribe(self, session: Session, op: Unsubscribe) -> None:
        name = clean_name(op.topic)
        sub = session.subscriptions.get(name)
        if sub is None:
            raise BridgeError(f"not subscribed to {name}")
        if op.id is not None and op.id in sub.ids:
            del sub.ids[op.id]
        elif op.id is not None:
            raise BridgeError(f"no subscription with id {op.id!r} on {name}")
        if op.id is None or not sub.ids:
            self._drop_subscription(session, name)
        else:
            sub.merge(self.config.send_queue_length)

    # ---------------------------------------------------------------- services
    def _op_call_service(self, session: Session, op: CallService) -> None:
        service, call_id = op.service, op.id
        if isinstance(service, str) and "#" in service:  # old "service#id" form (rosbridge.md §1.4)
            service, _, legacy = service.partition("#")
            call_id = call_id if call_id is not None else legacy
        try:
            name = clean_name(service, "service")
        except BridgeError as e:
            session.send_op(ServiceResponseOut(op.service, str(e), False, call_id))
            session.report("error", f"call_service: {e}", call_id)
            return
        asyncio.ensure_future(self._call_service(session, name, op, call_id))

    async def _call_service(self, session: Session, name: str, op: CallService, call_id) -> None:
        entry = self.services.get(name)
        try:
            if entry is None:
                raise ServiceFailure(f"service {name} does not exist")
            args = op.args if op.args is not None else {}
            if isinstance(args, list):  # positional arguments, in field order
                fields = entry.spec.request.field_names
                if len(args) > len(fields):
                    raise ServiceFailure(f"{name}: {len(args)} arguments for fields {fields}")
                args = dict(zip(fields, args, strict=False))
            try:
                request = from_wire(self.registry, entry.spec.request, args, "args")
            except MessageError as e:
                raise ServiceFailure(str(e)) from None
            timeout = op.timeout if op.timeout and op.timeout > 0 else self.config.service_timeout
            if entry.handler is not None:
                values = await entry.handler(request, session)
            else:
                values = await self._call_client_service(entry, request, timeout)
            try:
                values = from_wire(self.registry, entry.spec.response, values, "values")
            except MessageError as e:
                raise ServiceFailure(f"{name} gave a bad response: {e}") from None
            session.send_op(ServiceResponseOut(name, values, True, call_id))
        except ServiceFailure as e:
            session.send_op(ServiceResponseOut(name, str(e), False, call_id))
            session.report("warning", f"call_service: {e}", call_id)
        except asyncio.CancelledError:
            raise
        except Exception as e:
            _log.exception("service %s failed", name)
            session.send_op(ServiceResponseOut(name, f"{name} failed: {e}", False, call_id))

    async def _call_client_service(self, entry: ServiceEntry, request: dict, timeout: float):
        provider = entry.provider
        assert provider is not None
        request_id = f"service_request:{entry.name}:{next(self._counter)}"
        future = asyncio.get_running_loop().create_future()
        self._pending_calls[request_id] = (future, provider)
        provider.send_op(CallServiceOut(entry.name, request, request_id))
        try:
            return await asyncio.wait_for(future, timeout)
        except TimeoutError:
            raise ServiceFailure(
                f"{entry.name}: no response from its provider in {timeout:g} s"
            ) from None
        finally:
            self._pending_calls.pop(request_id, None)

    def _op_service_response(self, session: Session, op: ServiceResponse) -> None:
        pending = self._pending_calls.get(op.id) if isinstance(op.id, str) else None
        if pending is None or pending[1] is not session or pending[0].done():
            raise BridgeError(f"no pending call with id {op.id!r}")
        future = pending[0]
        if isinstance(op.values, str):  # a provider may answer with an error text
            future.set_exception(ServiceFailure(op.values))
        else:
            future.set_result(op.values if isinstance(op.values, dict) else {})

    def _op_advertise_service(self, session: Session, op: AdvertiseService) -> None:
        name = clean_name(op.service, "service")
        spec = self.registry.service(op.type)
        old = self.services.get(name)
        if old is not None and old.handler is not None:
            raise BridgeError(f"service {name} is provided by the simulator ({old.node})")
        if old is not None:
            _log.warning("service %s re-advertised by %s", name, session.name)
        self.services[name] = ServiceEntry(name, spec.name, spec, BRIDGE_NODE, provider=session)
        session.services.add(name)

    def _op_unadvertise_service(self, session: Session, op: UnadvertiseService) -> None:
        name = clean_name(op.service, "service")
        entry = self.services.get(name)
        if entry is None or entry.provider is not session:
            raise BridgeError(f"service {name} is not advertised by this client")
        del self.services[name]
        session.services.discard(name)

    # ---------------------------------------------------------------- actions (ROS 2)
    def _op_advertise_action(self, session: Session, op: AdvertiseAction) -> None:
        name = clean_name(op.action, "action")
        spec = self.registry.action(op.type)
        old = self.actions.get(name)
        if old is not None and old.handler is not None:
            raise BridgeError(f"action {name} is provided by the simulator ({old.node})")
        self.actions[name] = ActionEntry(name, spec.name, spec, BRIDGE_NODE, provider=session)
        session.actions.add(name)

    def _op_unadvertise_action(self, session: Session, op: UnadvertiseAction) -> None:
        name = clean_name(op.action, "action")
        entry = self.actions.get(name)
        if entry is None or entry.provider is not session:
            raise BridgeError(f"action {name} is not advertised by this client")
        del self.actions[name]
        session.actions.discard(name)
        for key, route in list(self._goals.items()):
            if route.action == name and route.provider_id is not None:
                self._finish_goal(key, "goal aborted: action server went away", "ABORTED", False)

    def _op_send_action_goal(self, session: Session, op: SendActionGoal) -> None:
        name = clean_name(op.action, "action")
        entry = self.actions.get(name)

        def fail(text: str) -> None:
            session.send_op(ActionResultOut(name, text, GOAL_STATUS["UNKNOWN"], False, op.id))
            session.report("warning", f"send_action_goal: {text}", op.id)

        if entry is None:
            return fail(f"action {name} does not exist")
        try:
            if split_type(op.action_type)[0] != entry.type:
                return fail(f"action {name} has type {entry.type}, not {op.action_type}")
            args = op.args if op.args is not None else {}
            if isinstance(args, list):
                args = dict(zip(entry.spec.goal.field_names, args, strict=False))
            goal = from_wire(self.registry, entry.spec.goal, args, "args")
        except (MessageError, TypeNameError) as e:
            return fail(str(e))
        key = (session, op.id)
        route = GoalRoute(name, session, op.id, op.feedback)
        self._goals[key] = route
        if entry.handler is not None:
            route.task = asyncio.ensure_future(self._run_goal(entry, key, route, goal))
        else:
            assert entry.provider is not None
            route.provider_id = f"action_goal:{name}:{next(self._counter)}"
            self._goals[route.provider_id] = route
            entry.provider.send_op(
                SendActionGoalOut(
                    name,
                    self.registry.wire_name(entry.type, "action"),
                    goal,
                    True,
                    route.provider_id,
                )
            )

    async def _run_goal(self, entry: ActionEntry, key, route: GoalRoute, goal: dict) -> None:
        def feedback(values: dict) -> None:
            if route.feedback and key in self._goals:
                route.caller.send_op(ActionFeedbackOut(route.action, values, route.caller_id))

        try:
            assert entry.handler is not None
            result = await entry.handler(goal, feedback)
            result = from_wire(self.registry, entry.spec.result, result, "result")
            self._finish_goal(key, result, "SUCCEEDED", True)
        except asyncio.CancelledError:
            self._finish_goal(key, {}, "CANCELED", True)
        except (ServiceFailure, MessageError) as e:
            self._finish_goal(key, str(e), "ABORTED", False)
        except Exception as e:
            _log.exception("action %s failed", entry.name)
            self._finish_goal(key, f"{entry.name} failed: {e}", "ABORTED", False)

    def _finish_goal(self, key, values, status: str, result: bool) -> None:
        route = self._goals.pop(key, None)
        if route is None:
            return
        other = route.provider_id if key != route.provider_id else (route.caller, route.caller_id)
        self._goals.pop(other, None)
        if not route.caller.closed:
            route.caller.send_op(
                ActionResultOut(route.action, values, GOAL_STATUS[status], result, route.caller_id)
            )

    def _op_cancel_action_goal(self, session: Session, op: CancelActionGoal) -> None:
        route = self._goals.get((session, op.id))
        if route is None:
            raise BridgeError(f"no goal with id {op.id!r} in flight")
        if route.task is not None:
            route.task.cancel()
            return
        entry = self.actions.get(route.action)
        if entry is not None and entry.provider is not None:
            entry.provider.send_op(CancelActionGoalOut(route.action, route.provider_id))

    def _provider_route(self, session: Session, op_id, action: str) -> GoalRoute:
        route = self._goals.get(op_id) if isinstance(op_id, str) else None
        entry = self.actions.get(clean_name(action, "action"))
        if route is None or entry is None or entry.provider is not session:
            raise BridgeError(f"no goal {op_id!r} of action {action} sent to this client")
        return route

    def _op_action_feedback(self, session: Session, op: ActionFeedback) -> None:
        route = self._provider_route(session, op.id, op.action)
        entry = self.actions[route.action]
        values = from_wire(self.registry, entry.spec.feedback, op.values, "values")
        if route.feedback and not route.caller.closed:
            route.caller.send_op(ActionFeedbackOut(route.action, values, route.caller_id))

    def _op_action_result(self, session: Session, op: ActionResult) -> None:
        route = self._provider_route(session, op.id, op.action)
        entry = self.actions[route.action]
        if not op.result:
            values: dict | str = op.values if isinstance(op.values, str) else "aborted"
            status = op.status
        else:
            values = from_wire(self.registry, entry.spec.result, op.values, "values")
            status = op.status
        statuses = {v: k for k, v in GOAL_STATUS.items()}
        if status not in statuses:
            raise BridgeError(f"action_result: unknown goal status {status}")
        self._finish_goal(op.id, values, statuses[status], op.result)

    # ================================================================ introspection
    def topic_type(self, name: str) -> str:
        topic = self.topics.get(name)
        return self.registry.wire_name(topic.type) if topic else ""

    def message_spec(self, type_name: str) -> MsgSpec:
        return self.registry.message(type_name)

    def stats(self) -> dict:
        return {
            "sessions": [s.stats() for s in self.sessions],
            "topics": {n: t.published for n, t in self.topics.items()},
        }
