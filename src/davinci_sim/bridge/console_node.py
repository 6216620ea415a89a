"""The console, foot pedals and teleoperations over the bridge (dvrk.md §2.3, §4.3).

The simulation's components are found by what their ``snapshot()`` holds, not by their
class, so this layer depends only on their public methods and published state:

* the console (``teleop_enabled``, ``buttons``, ``selected`` …): ``/console/teleop/*``,
  ``/console/{clutch,camera,operator_present}``, ``/console/emulate_*`` and the raw pedals
  ``/footpedals/<pedal>`` (``sensor_msgs/Joy``: ``[1]`` pressed, ``[0]`` released, ``[2]``
  quick tap);
* each PSM teleoperation (``current_state``, ``mtm``, ``psm`` …) under ``/<MTM>_<PSM>/``;
* the ECM teleoperation (``current_state`` without ``psm``) under ``/MTML_MTMR_ECM/``.

State topics are published when the value changes (and latched, so a new subscriber gets the
current value): from the component's events when the handle delivers them, otherwise by
comparing snapshots at ``rate``. Commands call the component's methods through the handle.
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from davinci_sim.bridge import dvrk_messages as m
from davinci_sim.bridge.rosbridge.graph import Topic
from davinci_sim.bridge.rosbridge.publisher import PeriodicTask
from davinci_sim.sim.types import CartesianPose

if TYPE_CHECKING:
    from davinci_sim.bridge.rosbridge.core import Bridge
    from davinci_sim.bridge.rosbridge.session import Session
    from davinci_sim.sim.handle import SimHandle, Snapshot

_log = logging.getLogger("davinci_sim.bridge")

NODE = "/davinci_sim/console"
PEDALS = ("clutch", "camera", "cam_minus", "cam_plus", "bicoag", "coag")
CONSOLE_BUTTONS = ("clutch", "camera", "operator_present")
#: What ``/console/teleop/scale`` says before any ``set_scale``: the dVRK's console emits the
#: default PSM teleoperation scale when it starts (dvrk.md 4.1: 0.2; sawIntuitiveResearchKit's
#: console ``Startup``), so ``dvrk.console.teleop_get_scale()`` reads it, not 0.
STARTUP_SCALE = 0.2


def kind_of(state: Any) -> str | None:
    """``console``, ``teleop_psm``, ``teleop_ecm`` or None, from a component's snapshot."""
    if all(hasattr(state, f) for f in ("teleop_enabled", "buttons", "selected")):
        return "console"
    if all(hasattr(state, f) for f in ("current_state", "desired_state", "following")):
        return "teleop_psm" if hasattr(state, "psm") and hasattr(state, "mtm") else "teleop_ecm"
    return None


@dataclass(frozen=True)
class Field:
    """A published state field: ``attr`` of the snapshot (or event name) → topic."""

    attr: str
    suffix: str
    type: str
    build: Callable[[m.Dialect, Any, float], dict]


def _string(d, v, t):
    return {"data": str(v)}


def _bool(d, v, t):
    return {"data": bool(v)}


def _float(d, v, t):
    return {"data": float(v)}


def _joy(d, v, t):
    return m.joy(d, [1 if v else 0], t)


def _quaternion(d, R, t):
    x, y, z, w = m.quaternion_from_matrix(np.asarray(R))
    return {"header": d.header(t, ""), "quaternion": {"x": x, "y": y, "z": z, "w": w}}


# dvrk.md 4.3 (``rotation_locked``/``translation_locked`` are Joy there).
TELEOP_PSM_FIELDS = (
    Field("current_state", "current_state", "std_msgs/String", _string),
    Field("desired_state", "desired_state", "std_msgs/String", _string),
    Field("following", "following", "std_msgs/Bool", _bool),
    Field("scale", "scale", "std_msgs/Float64", _float),
    Field("rotation_locked", "rotation_locked", "sensor_msgs/Joy", _joy),
    Field("translation_locked", "translation_locked", "sensor_msgs/Joy", _joy),
    Field("align_mtm", "align_mtm", "std_msgs/Bool", _bool),
    Field("alignment_offset", "alignment_offset", "geometry_msgs/QuaternionStamped",
          _quaternion),
)  # fmt: skip
TELEOP_ECM_FIELDS = TELEOP_PSM_FIELDS[:4]
#: Fields a teleoperation also announces as events (the others are only in its snapshots).
TELEOP_EVENTS = frozenset(
    ("current_state", "desired_state", "following", "scale", "rotation_locked",
     "translation_locked", "align_mtm")
)  # fmt: skip


@dataclass(frozen=True)
class Command:
    """``/<prefix>/<suffix>`` → ``component.method(*convert(msg))``."""

    suffix: str
    type: str
    method: str
    convert: Callable[[dict], tuple]


TELEOP_PSM_COMMANDS = (
    Command("state_command", "crtk_msgs/StringStamped", "state_command",
            lambda msg: (msg["string"],)),
    Command("set_scale", "std_msgs/Float64", "set_scale", lambda msg: (msg["data"],)),
    Command("lock_rotation", "std_msgs/Bool", "lock_rotation", lambda msg: (msg["data"],)),
    Command("lock_translation", "std_msgs/Bool", "lock_translation", lambda msg: (msg["data"],)),
    Command("set_align_MTM", "std_msgs/Bool", "set_align_mtm", lambda msg: (msg["data"],)),
    Command("set_align_mtm", "std_msgs/Bool", "set_align_mtm", lambda msg: (msg["data"],)),
)  # fmt: skip
TELEOP_ECM_COMMANDS = TELEOP_PSM_COMMANDS[:2]
CONSOLE_COMMANDS = (
    Command("teleop/enable", "std_msgs/Bool", "teleop_enable", lambda msg: (msg["data"],)),
    Command("teleop/set_scale", "std_msgs/Float64", "set_scale", lambda msg: (msg["data"],)),
    Command("teleop/select", "std_msgs/String", "select_teleop", lambda msg: (msg["data"],)),
    Command("teleop/unselect", "std_msgs/String", "unselect_teleop", lambda msg: (msg["data"],)),
    *(
        Command(f"emulate_{b}", "sensor_msgs/Joy", "button",
                lambda msg, b=b: (b, list(msg["buttons"])))
        for b in (*CONSOLE_BUTTONS, "coag")
    ),
)  # fmt: skip


class _Component:
    def __init__(self, name: str, kind: str) -> None:
        self.name = name
        self.kind = kind
        self.fields: dict[str, tuple[Topic, Field]] = {}
        self.last: dict[str, Any] = {}
        self.evented = False
        self.topics: dict[str, Topic] = {}


class ConsoleNode:
    """Serves the console and teleoperation components of ``handle``'s simulation.

    Args:
        handle: the running simulation.
        rate: how often snapshots are compared and the teleoperations' ``MTM/measured_cp``
            and ``PSM/setpoint_cp`` are published, Hz.
    """

    def __init__(self, handle: SimHandle, *, rate: float = 100.0) -> None:
        if not 0 < rate <= 1000:
            raise ValueError(f"rate must be in ]0, 1000] Hz, got {rate!r}")
        self.handle = handle
        self.rate = rate
        self.components: dict[str, _Component] = {}
        self._task: PeriodicTask | None = None
        self._unsubscribe: Callable[[], None] | None = None

    # ------------------------------------------------------------------ setup
    def attach(self, bridge: Bridge) -> None:
        self.bridge = bridge
        self.loop = asyncio.get_running_loop()
        snap = self.handle.snapshot()
        for name, state in (snap.extras or {}).items():
            kind = kind_of(state)
            if kind is not None:
                self.components[name] = c = _Component(name, kind)
                getattr(self, f"_advertise_{kind}")(c)
        if not self.components:
            _log.info("no console or teleoperation components: no console topics")
            return
        self._publish_changes(snap)
        self._unsubscribe = self.handle.subscribe(self._event_from_loop)
        self._task = PeriodicTask(1.0 / self.rate, self._tick)
        self._task.start()

    async def detach(self) -> None:
        if self._unsubscribe is not None:
            self._unsubscribe()
        if self._task is not None:
            await self._task.stop()
        self.bridge.remove_node(NODE)

    def _adv(self, c: _Component, name: str, type_name: str, latch: bool = True) -> Topic:
        topic = self.bridge.advertise(name, type_name, node=NODE, latch=latch)
        c.topics[name] = topic
        return topic

    def _listen(self, c: _Component, prefix: str, commands) -> None:
        for cmd in commands:
            self.bridge.listen(f"{prefix}/{cmd.suffix}", cmd.type, self._command(c, cmd),
                               node=NODE)  # fmt: skip

    def _advertise_console(self, c: _Component) -> None:
        self._adv(c, "/console/teleop/enabled", "std_msgs/Bool")
        self._adv(c, "/console/teleop/scale", "std_msgs/Float64")
        self._adv(c, "/console/teleop/selected", "std_msgs/String", latch=False)
        self._adv(c, "/console/teleop/unselected", "std_msgs/String", latch=False)
        for b in CONSOLE_BUTTONS:
            self._adv(c, f"/console/{b}", "sensor_msgs/Joy", latch=False)
        for p in PEDALS:
            self._adv(c, f"/footpedals/{p}", "sensor_msgs/Joy", latch=False)
        self._listen(c, "/console", CONSOLE_COMMANDS)

    def _advertise_teleop(self, c: _Component, fields, commands) -> None:
        for f in fields:
            c.fields[f.attr] = (self._adv(c, f"/{c.name}/{f.suffix}", f.type), f)
        self._listen(c, f"/{c.name}", commands)

    def _advertise_teleop_psm(self, c: _Component) -> None:
        self._advertise_teleop(c, TELEOP_PSM_FIELDS, TELEOP_PSM_COMMANDS)
        self._adv(c, f"/{c.name}/MTM/measured_cp", "geometry_msgs/PoseStamped", latch=False)
        self._adv(c, f"/{c.name}/PSM/setpoint_cp", "geometry_msgs/PoseStamped", latch=False)

    def _advertise_teleop_ecm(self, c: _Component) -> None:
        self._advertise_teleop(c, TELEOP_ECM_FIELDS, TELEOP_ECM_COMMANDS)

    # ------------------------------------------------------------------ publishing
    def _tick(self) -> None:
        snap = self.handle.snapshot()
        self._publish_changes(snap)
        self._publish_poses(snap)

    def _publish_changes(self, snap: Snapshot) -> None:
        for c in self.components.values():
            state = (snap.extras or {}).get(c.name)
            if state is None:
                continue
            if c.kind == "console":
                self._console_changes(c, state)
                continue
            for attr, (topic, f) in c.fields.items():
                # Event-driven fields are not diffed: a snapshot may be older than the event.
                if not (c.evented and attr in TELEOP_EVENTS):
                    self._changed(c, attr, getattr(state, attr, None), topic, f)

    def _changed(self, c: _Component, attr: str, value: Any, topic: Topic, f: Field) -> None:
        if value is None or (isinstance(value, float) and math.isnan(value)):
            return
        old = c.last.get(attr)
        same = old is not None and (
            np.array_equal(old, value) if isinstance(value, np.ndarray) else old == value
        )
        if not same:
            c.last[attr] = value
            self.bridge.publish(topic, f.build(self.bridge.dialect, value, self.bridge.now()))

    def _console_changes(self, c: _Component, s: Any) -> None:
        b, d, now = self.bridge, self.bridge.dialect, self.bridge.now()
        if c.evented:
            return
        if c.last.get("teleop_enabled") != s.teleop_enabled:
            c.last["teleop_enabled"] = s.teleop_enabled
            b.publish(c.topics["/console/teleop/enabled"], {"data": bool(s.teleop_enabled)})
        scale = s.scale
        if (scale is None or math.isnan(scale)) and "scale" not in c.last:
            scale = STARTUP_SCALE  # never set: the value the dVRK's console starts with
        if scale is not None and not math.isnan(scale) and c.last.get("scale") != scale:
            c.last["scale"] = scale
            b.publish(c.topics["/console/teleop/scale"], {"data": float(scale)})
        before = set(c.last.get("selected", ()))
        after = set(s.selected)
        if "selected" in c.last:
            for name in sorted(after - before):
                b.publish(c.topics["/console/teleop/selected"], {"data": name})
            for name in sorted(before - after):
                b.publish(c.topics["/console/teleop/unselected"], {"data": name})
        c.last["selected"] = tuple(s.selected)
        buttons = dict(s.buttons)
        old = c.last.get("buttons")
        if old is not None:
            for name, pressed in buttons.items():
                if old.get(name) != pressed:
                    self._button(c, name, [1 if pressed else 0], now, d)
        c.last["buttons"] = buttons

    def _button(self, c: _Component, name: str, joy: list[int], now: float, d) -> None:
        for topic_name in (f"/console/{name}", f"/footpedals/{name}"):
            topic = c.topics.get(topic_name)
            if topic is not None:
                self.bridge.publish(topic, m.joy(d, joy, now))

    def _publish_poses(self, snap: Snapshot) -> None:
        b, d = self.bridge, self.bridge.dialect
        for c in self.components.values():
            if c.kind != "teleop_psm":
                continue
            state = (snap.extras or {}).get(c.name)
            if state is None:
                continue
            t = time.time() if b.config.stamp_clock == "wall" else snap.time
            topic = c.topics[f"/{c.name}/MTM/measured_cp"]
            if topic.subscriptions and getattr(state, "T_hrsv_mtm", None) is not None:
                cp = CartesianPose(state.T_hrsv_mtm, "HRSV", state.mtm)
                b.publish(topic, m.pose_stamped(d, cp, t, topic.next_seq()))
            topic = c.topics[f"/{c.name}/PSM/setpoint_cp"]
            arm = snap.arms.get(state.psm)
            if topic.subscriptions and arm is not None:
                b.publish(topic, m.pose_stamped(d, arm.setpoint_cp, t, topic.next_seq()))

    # ------------------------------------------------------------------ events
    def _event_from_loop(self, source: str, event: str, payload: object) -> None:
        if source in self.components:
            try:
                self.loop.call_soon_threadsafe(self._on_event, source, event, payload)
            except RuntimeError:
                pass

    def _on_event(self, source: str, event: str, payload: Any) -> None:
        """Events of components whose runner forwards them: exact, and carry quick taps."""
        c = self.components[source]
        b, d, now = self.bridge, self.bridge.dialect, self.bridge.now()
        c.evented = True
        if c.kind == "console":
            if event == "teleop_enabled":
                b.publish(c.topics["/console/teleop/enabled"], {"data": bool(payload)})
            elif event == "scale":
                b.publish(c.topics["/console/teleop/scale"], {"data": float(payload)})
            elif event in ("teleop_selected", "teleop_unselected"):
                topic = c.topics["/console/teleop/" + event.split("_")[1]]
                b.publish(topic, {"data": str(payload)})
            elif isinstance(payload, list | tuple) and len(payload) == 1:
                self._button(c, event, [int(payload[0])], now, d)
            return
        entry = c.fields.get(event)
        if entry is not None and event in TELEOP_EVENTS:
            topic, f = entry
            c.last[event] = payload
            b.publish(topic, f.build(d, payload, now))

    # ------------------------------------------------------------------ commands
    def _command(self, c: _Component, cmd: Command):
        send = component_sender(self.handle, c.name, cmd)  # the path client mode uses too

        def on_message(msg: dict, session: Session | None) -> None:
            send(msg, lambda text: self._to_loop(self._refused, session, text))

        return on_message

    def _to_loop(self, fn, *args) -> None:
        try:
            self.loop.call_soon_threadsafe(fn, *args)
        except RuntimeError:  # the loop is closed: the server has stopped
            pass

    def _refused(self, session: Session | None, text: str) -> None:
        if session is not None:
            session.report("error", text)
        else:
            _log.warning("%s", text)


def component_sender(handle: SimHandle, name: str, cmd: Command):
    """``send(msg, refused)``: ``name.method(*cmd.convert(msg))`` through the handle;
    ``refused(text)`` (maybe from the simulation's thread) if the component refuses it."""

    def send(msg: dict, refused: Callable[[str], None]) -> None:
        def done(future) -> None:
            exc = future.exception()
            result = None if exc is not None else future.result()
            if exc is None and not (hasattr(result, "accepted") and not result.accepted):
                return
            refused(f"{name}/{cmd.suffix}: {exc if exc is not None else result.message}")

        handle.call(name, cmd.method, *cmd.convert(msg)).add_done_callback(done)

    return send
