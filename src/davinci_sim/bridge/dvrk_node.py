"""The dVRK CRTK ROS API of every simulated arm, served by the bridge (dvrk.md §2).

For each arm of the simulation (``PSM1..3``, ``ECM``, ``MTML``, ``MTMR``, ``SUJ/*``), under
``/<ARM>/``:

* state topics from the handle's snapshots, published at ``rate`` (100 Hz by default, the
  dVRK's; up to 1 kHz) and only while someone subscribes: ``measured_js``, ``setpoint_js``,
  ``measured_cp``, ``setpoint_cp``, ``local/*_cp``, ``measured_cv``, ``local/measured_cv``,
  ``jaw/*_js`` (PSM), ``gripper/measured_js`` (MTM); ``/tf`` at ``tf_rate`` (50 Hz) with every
  ``measured_cp`` (dvrk.md 2.1);
* values the snapshot lacks, asked from the loop only while subscribed: ``body|spatial/
  measured_cf``, ``body|spatial/jacobian``, ``trajectory_j/ratio``, ``orientation_locked``;
* events: ``operating_state`` (latched, so a new subscriber gets the current state),
  ``error``/``warning``/``status``, ``goal_reached`` at the end of a move; an operating
  state goes out after the state topics of a snapshot of its tick (at most
  :data:`EVENT_HOLD_MAX` later), so a client that sees a move end reads joints from then;
* commands (the tables below) and the services ``forward_kinematics``,
  ``local/forward_kinematics``, ``inverse_kinematics``, ``operating_state``, ``crtk_version``.

A message that does not validate never reaches the simulation; a command the arm refuses is
reported on the arm's ``error`` topic (by the arm) and, if asked for, as a ``status`` to the
client that sent it.
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from davinci_sim.bridge import dvrk_messages as m
from davinci_sim.bridge.dvrk_commands import Refusal, command_sender, error_text
from davinci_sim.bridge.dvrk_topics import (
    ARMS,
    COMMAND_TOPICS,
    CONSTANT_TOPICS,
    CRTK_VERSION,
    EVENT_TOPICS,
    GRIPPER_CLOSED_BELOW,
    NODE,
    POLLED_TOPICS,
    STATE_TOPICS,
    ArmInfo,
    CommandTopic,
    PolledTopic,
    StateTopic,
)
from davinci_sim.bridge.rosbridge.core import ServiceFailure
from davinci_sim.bridge.rosbridge.graph import Topic
from davinci_sim.bridge.rosbridge.publisher import PeriodicTask

if TYPE_CHECKING:
    from davinci_sim.bridge.rosbridge.core import Bridge
    from davinci_sim.bridge.rosbridge.session import Session
    from davinci_sim.sim.handle import SimHandle, Snapshot

_log = logging.getLogger("davinci_sim.bridge")

#: An operating-state event waits for a snapshot of its tick at most this long, wall s (a
#: few state periods: snapshots come every 10 ms of simulation; after a stop, not at all).
EVENT_HOLD_MAX = 0.1


# =========================================================================== the node
class _Arm:
    """The topics of one arm."""

    def __init__(self, info: ArmInfo) -> None:
        self.info = info
        self.state: list[tuple[Topic, StateTopic]] = []
        self.polled: list[tuple[Topic, PolledTopic]] = []
        self.events: dict[str, Topic] = {}
        self.operating_state: Topic | None = None
        self.goal_reached: Topic | None = None
        self.busy = False
        self.last_event_time = -1.0
        self.last_state: Any = None
        """The last operating state published (an event's, or the snapshot's safety net)."""
        self.pending: list[tuple[Any, float]] = []
        """Operating-state events newer than the snapshot, with their arrival (monotonic s):
        published after the state topics of a snapshot that covers them."""
        self.gripper_closed: Topic | None = None
        self.closed: bool | None = None


class DvrkNode:
    """Serves the dVRK API of every arm of ``handle``'s simulation.

    Args:
        handle: the running simulation.
        rate: publish rate of the state topics, Hz (the dVRK's default 100; up to 1000).
        tf_rate: publish rate of ``/tf``, Hz (the dVRK's default 50).
        arms: the arms to serve (default: all of the simulation).
    """

    def __init__(
        self,
        handle: SimHandle,
        *,
        rate: float = 100.0,
        tf_rate: float = 50.0,
        arms: tuple[str, ...] | None = None,
    ) -> None:
        if not 0 < rate <= 1000:
            raise ValueError(f"rate must be in ]0, 1000] Hz, got {rate!r}")
        if not 0 < tf_rate <= 1000:
            raise ValueError(f"tf_rate must be in ]0, 1000] Hz, got {tf_rate!r}")
        self.handle = handle
        self.rate = rate
        self.tf_rate = tf_rate
        self._only = arms
        self.arms: dict[str, _Arm] = {}
        self._tasks: list[PeriodicTask] = []
        self._unsubscribe: Callable[[], None] | None = None
        self._polling: set[Topic] = set()
        self.event_sinks: list[Callable[[str, str, object], bool]] = []
        """Handlers for events of non-arm sources (console, teleops): return True if used."""
        self.published = 0
        self.state_time = -math.inf
        """Simulation time (s) of the snapshot whose state topics went out last."""

    # ------------------------------------------------------------------ setup
    def attach(self, bridge: Bridge) -> None:
        self.bridge = bridge
        self.loop = asyncio.get_running_loop()
        d = bridge.dialect
        # Events first, then the snapshot: an event between the two is queued on the loop
        # and applied after this (a snapshot may be a few ticks old).
        self._unsubscribe = self.handle.subscribe(self._event_from_loop)
        snap = self.handle.snapshot()
        if bridge.config.stamp_clock == "sim":
            bridge.clock = lambda: self.handle.snapshot().time
        for name, a in snap.arms.items():
            if self._only is not None and name not in self._only:
                continue
            arm = _Arm(ArmInfo(name, a.arm_type, tuple(a.measured_js.name)))
            self.arms[name] = arm
            self._advertise_arm(arm)
            s = a.operating_state
            bridge.publish(arm.operating_state, m.operating_state(d, s, bridge.now()))
            arm.busy = s.is_busy
        self.tf = bridge.advertise("/tf", "tf2_msgs/TFMessage", node=NODE)
        # ROS's simulated time (what a node with use_sim_time reads), at the state rate
        self.clock = bridge.advertise("/clock", "rosgraph_msgs/Clock", node=NODE)
        self._tasks = [
            PeriodicTask(1.0 / self.rate, self._publish_state),
            PeriodicTask(1.0 / self.tf_rate, self._publish_tf),
        ]
        for task in self._tasks:
            task.start()

    async def detach(self) -> None:
        if self._unsubscribe is not None:
            self._unsubscribe()
        for task in self._tasks:
            await task.stop()
        self.bridge.remove_node(NODE)

    def _topic(self, arm: _Arm, suffix: str) -> str:
        return f"/{arm.info.name}/{suffix}"

    def _advertise_arm(self, arm: _Arm) -> None:
        b, kind = self.bridge, arm.info.arm_type
        for spec in STATE_TOPICS:
            if kind in spec.arm_types:
                arm.state.append((b.advertise(self._topic(arm, spec.suffix), spec.type,
                                              node=NODE), spec))  # fmt: skip
        for spec in POLLED_TOPICS:
            if kind in spec.arm_types:
                arm.polled.append((b.advertise(self._topic(arm, spec.suffix), spec.type,
                                               node=NODE), spec))  # fmt: skip
        for spec in COMMAND_TOPICS:
            if kind in spec.arm_types:
                b.listen(self._topic(arm, spec.suffix), spec.type,
                         self._command_listener(arm, spec), node=NODE)  # fmt: skip
        for event, type_name in EVENT_TOPICS.items():
            arm.events[event] = b.advertise(self._topic(arm, event), type_name, node=NODE)
        arm.operating_state = b.advertise(
            self._topic(arm, "operating_state"), "crtk_msgs/OperatingState", node=NODE, latch=True
        )
        arm.goal_reached = b.advertise(self._topic(arm, "goal_reached"), "std_msgs/Bool",
                                       node=NODE)  # fmt: skip
        if kind in CONSTANT_TOPICS:
            suffix, value = CONSTANT_TOPICS[kind]
            topic = b.advertise(self._topic(arm, suffix), "std_msgs/String", node=NODE, latch=True)
            b.publish(topic, {"data": value})
        if kind == "MTM":
            arm.gripper_closed = b.advertise(self._topic(arm, "gripper/closed"), "std_msgs/Bool",
                                             node=NODE, latch=True)  # fmt: skip
        self._advertise_services(arm)

    # ------------------------------------------------------------------ publishing
    def _stamp(self, sim_time: float) -> float:
        return sim_time if self.bridge.config.stamp_clock == "sim" else time.time()

    def _publish_state(self) -> None:
        snap: Snapshot = self.handle.snapshot()
        self._check_grippers(snap)
        try:
            self._publish_state_topics(snap)
            self.state_time = snap.time
            if self.clock.subscriptions:  # (after the states: a script woken by it reads them)
                self.bridge.publish(self.clock, {"clock": self.bridge.dialect.stamp(snap.time)})
        finally:
            # the events this snapshot covers, after its state; then the safety net (which
            # must not publish the snapshot's state ahead of events still held)
            self._flush_operating_states(snap.time)
            self._check_operating_states(snap)

    def _publish_state_topics(self, snap: Snapshot) -> None:
        b, d = self.bridge, self.bridge.dialect
        for arm in self.arms.values():
            for topic, spec in arm.state:
                if not topic.subscriptions:
                    continue
                a = snap.arms.get(arm.info.name)
                if a is None:
                    continue
                msg = spec.build(d, a, self._stamp(snap.time), topic.next_seq())
                if msg is not None:
                    b.publish(topic, msg)
                    self.published += 1
            for topic, spec in arm.polled:
                if topic.subscriptions and topic not in self._polling:
                    self._poll(arm, topic, spec)

    def _poll(self, arm: _Arm, topic: Topic, spec: PolledTopic) -> None:
        target = arm.info.name + (f"/{spec.target}" if spec.target else "")
        self._polling.add(topic)
        future = self.handle.call(target, spec.method)

        def done(f) -> None:
            self._polling.discard(topic)
            if f.exception() is not None:
                _log.warning("%s: %s", topic.name, f.exception())
                return
            value = f.result()
            d, stamp = self.bridge.dialect, self._stamp(self.handle.snapshot().time)
            self.bridge.publish(topic, spec.build(d, value, arm.info.name, stamp, topic.next_seq()))

        future.add_done_callback(lambda f: self.loop.call_soon_threadsafe(done, f))

    def _publish_tf(self) -> None:
        if not self.tf.subscriptions:
            return
        snap = self.handle.snapshot()
        d = self.bridge.dialect
        stamp = self._stamp(snap.time)
        transforms = [
            m.transform_stamped(d, a.measured_cp, stamp)
            for name, a in snap.arms.items()
            if name in self.arms
        ]
        self.bridge.publish(self.tf, {"transforms": transforms})

    # ------------------------------------------------------------------ events
    def _event_from_loop(self, source: str, event: str, payload: object) -> None:
        """Called in the simulation's thread: hand over to the bridge's loop."""
        try:
            self.loop.call_soon_threadsafe(self._on_event, source, event, payload)
        except RuntimeError:  # the loop is closed: we are stopping
            pass

    def _on_event(self, source: str, event: str, payload: Any) -> None:
        arm = self.arms.get(source)
        if arm is None:
            for sink in self.event_sinks:
                if sink(source, event, payload):
                    return
            return
        b = self.bridge
        if event == "operating_state":
            # After the state topics of its tick: a client that sees a move end (not busy)
            # then reads measured_js gets the joints of that tick or later, not a snapshot
            # from before the end (a thread runner behind a busy loop: 100s of ms).
            arm.last_event_time = payload.timestamp  # (the safety net: this state came)
            # (a snapshot of time t was taken before the tick that starts at t: it covers
            # events of earlier ticks only. The snapshot whose state topics went out, not
            # the latest: after a stall of this loop the simulation's snapshots are ahead of
            # what the clients were sent, and the events would overtake their joints.)
            if not arm.pending and payload.timestamp < self.state_time:
                self._publish_operating_state(arm, payload)
            else:
                arm.pending.append((payload, time.monotonic()))
        elif event in arm.events:
            topic = arm.events[event]
            b.publish(topic, {"data": getattr(payload, "text", str(payload))})

    def _publish_operating_state(self, arm: _Arm, s) -> None:
        b, d = self.bridge, self.bridge.dialect
        assert arm.operating_state is not None and arm.goal_reached is not None
        arm.last_event_time = s.timestamp
        arm.last_state = s
        b.publish(
            arm.operating_state,
            m.operating_state(d, s, self._stamp(s.timestamp), arm.operating_state.next_seq()),
        )
        if arm.busy and not s.is_busy:  # end of a move (dvrk.md 2.2 goal_reached)
            b.publish(arm.goal_reached, {"data": True})
        arm.busy = s.is_busy

    def _flush_operating_states(self, snapshot_time: float) -> None:
        """Publish the pending operating-state events the snapshot of ``snapshot_time`` (s,
        simulation) covers, in order; one held longer than :data:`EVENT_HOLD_MAX` (wall s:
        snapshots that stopped coming) goes out anyway."""
        now = time.monotonic()
        for arm in self.arms.values():
            while arm.pending and (
                arm.pending[0][0].timestamp < snapshot_time
                or now - arm.pending[0][1] > EVENT_HOLD_MAX
            ):
                self._publish_operating_state(arm, arm.pending.pop(0)[0])

    def _check_operating_states(self, snap: Snapshot) -> None:
        """Safety net for a handle that loses events: publish a state the snapshot shows
        only if no event came for it (snapshots may be a tick behind the events)."""
        for name, arm in self.arms.items():
            a = snap.arms.get(name)
            topic = arm.operating_state
            if a is None or topic is None or topic.last is None:
                continue
            if arm.pending:  # (events are coming for it)
                continue
            s = a.operating_state
            last = topic.last.msg
            same = (last["state"], last["is_homed"], last["is_busy"]) == (
                s.state, s.is_homed, s.is_busy)  # fmt: skip
            if not same and snap.time > arm.last_event_time + 0.05:
                self._publish_operating_state(arm, s)

    def _check_grippers(self, snap: Snapshot) -> None:
        """``gripper/closed`` of the MTMs, published when it changes (dvrk.md 2.2)."""
        for name, arm in self.arms.items():
            a = snap.arms.get(name)
            if arm.gripper_closed is None or a is None or a.gripper_measured_js is None:
                continue
            closed = bool(a.gripper_measured_js.position[0] <= GRIPPER_CLOSED_BELOW)
            if closed != arm.closed:
                arm.closed = closed
                self.bridge.publish(arm.gripper_closed, {"data": closed})

    # ------------------------------------------------------------------ commands
    def _command_listener(self, arm: _Arm, spec: CommandTopic):
        send = command_sender(self.handle, arm.info, spec)  # the path client mode uses too

        def on_message(msg: dict, session: Session | None) -> None:
            send(msg, lambda r: self._to_loop(self._refused, arm, session, r))

        return on_message

    def _to_loop(self, fn, *args) -> None:
        """Run ``fn`` on the bridge's loop (from any thread); dropped once it has closed."""
        try:
            self.loop.call_soon_threadsafe(fn, *args)
        except RuntimeError:  # the loop is closed: the server has stopped
            pass

    def _refused(self, arm: _Arm, session: Session | None, refusal: Refusal) -> None:
        """A command that moved nothing: tell the client (status) and, when the arm did not
        already say it on its error channel, publish it on ``/<arm>/error``."""
        if refusal.publish_error:
            self.bridge.publish(arm.events["error"], {"data": error_text(arm.info.name, refusal)})
        if session is not None:
            session.report("error", refusal.text)
        else:
            _log.warning("%s", refusal.text)

    # ------------------------------------------------------------------ services
    def _advertise_services(self, arm: _Arm) -> None:
        b, name = self.bridge, arm.info.name

        async def call(target: str, method: str, *args):
            return await asyncio.wrap_future(self.handle.call(target, method, *args))

        async def crtk_version(req, session) -> dict:
            return {"success": True, "message": CRTK_VERSION}

        async def operating_state(req, session) -> dict:
            s = self.handle.snapshot().arms[name].operating_state
            latest = arm.last_state
            if latest is not None and latest.timestamp > s.timestamp:
                s = latest  # (the snapshot may be a tick behind the state the topic published)
            return {"operating_state": m.operating_state(b.dialect, s, self._stamp(s.timestamp))}

        def fk(target: str):
            async def handler(req, session) -> dict:
                jp = req["jp"]
                if not jp:
                    raise ServiceFailure("forward_kinematics: jp is empty")
                cp, result = await call(target, "forward_kinematics", np.asarray(jp))
                if cp is None:
                    return {"result": False, "message": result.message}
                return {"cp": m.pose(cp.T), "result": True, "message": ""}

            return handler

        async def ik(req, session) -> dict:
            try:
                T = m.pose_matrix(req["cp"])
            except m.CommandError as e:
                return {"result": False, "message": str(e)}
            q, result = await call(name, "inverse_kinematics", np.asarray(req["jp"]), T)
            if q is None:
                return {"result": False, "message": result.message}
            return {"jp": np.asarray(q).tolist(), "result": True, "message": ""}

        b.provide_service(f"/{name}/crtk_version", "std_srvs/Trigger", crtk_version, node=NODE)
        b.provide_service(f"/{name}/operating_state", "crtk_msgs/TriggerOperatingState",
                          operating_state, node=NODE)  # fmt: skip
        if arm.info.arm_type in ARMS:
            b.provide_service(f"/{name}/forward_kinematics", "crtk_msgs/QueryForwardKinematics",
                              fk(name), node=NODE)  # fmt: skip
            b.provide_service(f"/{name}/local/forward_kinematics",
                              "crtk_msgs/QueryForwardKinematics", fk(f"{name}/local"),
                              node=NODE)  # fmt: skip
            b.provide_service(f"/{name}/inverse_kinematics", "crtk_msgs/QueryInverseKinematics",
                              ik, node=NODE)  # fmt: skip
