"""The dVRK socket-streamer UDP JSON stream (sawSocketStreamer, dvrk.md §5).

For each configured arm, every ``period`` the streamer sends one datagram per read command to
``ip:port``, a compact JSON object with one key, the command name, whose value is the cisst
object as JSON: ``prmStateJoint`` (``Name``, ``Position``, ``Velocity``, ``Effort``,
``Timestamp``, ``AutomaticTimestamp``, ``Valid``), ``prmPositionCartesianGet`` (``Position``
{``Rotation`` 3x3, ``Translation``}, ``ReferenceFrame``, ``MovingFrame`` …). Events
(``operating_state``, and here by default the arm's ``error`` and ``warning`` messages) are
sent when they happen. Datagrams received on the same socket are commands:
``{"servo_jp": {"Goal": [q1, …]}}``, ``{"hold": ""}``, ``{"state_command": "enable"}`` …
(one object, one key per command, as the streamer's ``write-commands`` deserialise them).

Bad input changes nothing and the stream carries on, as on the other transports: a datagram
that is not one JSON object, names a command the stream does not accept, or whose payload has
the wrong shape is refused whole (none of its commands run) and answered with an
``{"error": "<ARM>: <why>"}`` datagram (to the stream's destination, and to the sender if it
is another address); a command the arm refuses (limits, state, NaN …) gets the arm's own
``error`` event. The dVRK's streamer only logs such errors; answering them is this project's
choice, and the ``error`` and ``warning`` events can be left out of ``write_events``.

Default destination ports: the dVRK examples' 48051 (PSM1), 48052 (PSM2), 48053 (ECM),
48054 (MTML); MTMR 48055 and PSM3 48056 are this project's choice. The JSON rendering of the
operating state's enum is not documented (dvrk.md §5); it is sent as its name, e.g.
``"State": "ENABLED"``.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from davinci_sim.bridge.rosbridge import codec
from davinci_sim.bridge.rosbridge.publisher import PeriodicTask
from davinci_sim.devices.streamer import encode_joint_state, encode_pose
from davinci_sim.sim.runtime.service import AsyncService

if TYPE_CHECKING:
    from davinci_sim.sim.handle import ArmSnapshot, SimHandle

_log = logging.getLogger("davinci_sim.bridge.udp")

DEFAULT_PORTS = {"PSM1": 48051, "PSM2": 48052, "ECM": 48053, "MTML": 48054, "MTMR": 48055,
                 "PSM3": 48056}  # fmt: skip
DEFAULT_READ = {
    "PSM": ("measured_js", "jaw/measured_js", "setpoint_cp", "jaw/setpoint_js"),
    "ECM": ("measured_js", "setpoint_cp"),
    "MTM": ("measured_js", "measured_cp", "gripper/measured_js"),
    "SUJ": ("measured_js", "measured_cp"),
}
DEFAULT_VOID = ("hold", "free")
DEFAULT_WRITE = {
    "PSM": ("servo_jp", "move_jp", "servo_jr", "move_jr", "servo_cp", "move_cp", "state_command",
            "jaw/servo_jp", "jaw/move_jp"),
    "ECM": ("servo_jp", "move_jp", "servo_jr", "move_jr", "servo_cp", "move_cp", "state_command"),
    "MTM": ("servo_jp", "move_jp", "servo_cp", "move_cp", "state_command", "servo_jf",
            "body/servo_cf", "spatial/servo_cf"),
    "SUJ": ("servo_jp", "move_jp", "state_command"),
}  # fmt: skip


class StreamError(ValueError):
    """An incoming command datagram that cannot be executed."""


@dataclass(frozen=True)
class StreamConfig:
    """One arm's stream (the keys of a dVRK ``streamer*.json``)."""

    arm: str
    port: int
    """Destination port of the outgoing datagrams."""
    ip: str = "127.0.0.1"
    """Destination address."""
    period: float = 0.01
    read_commands: tuple[str, ...] | None = None
    """Sent every period; None: the dVRK example's list for the arm type."""
    void_commands: tuple[str, ...] = DEFAULT_VOID
    write_commands: tuple[str, ...] | None = None
    write_events: tuple[str, ...] = ("operating_state", "error", "warning")
    """Events sent as they happen (the dVRK examples stream ``operating_state``; the arm's
    ``error`` and ``warning`` messages carry the refusals)."""
    bind_ip: str = "127.0.0.1"
    bind_port: int = 0
    """Local port of the socket (commands arrive there); 0: any free port."""

    def __post_init__(self) -> None:
        if not 0 < self.port < 65536 or not 0 <= self.bind_port < 65536:
            raise ValueError(f"{self.arm}: bad port {self.port} / bind port {self.bind_port}")
        if not self.period > 0:
            raise ValueError(f"{self.arm}: period must be > 0, got {self.period!r}")


# =========================================================================== cisst JSON
def state_joint(js) -> dict:
    """``prmStateJoint`` as cisst serialises it (codec of :mod:`davinci_sim.devices.streamer`)."""
    return encode_joint_state(
        js.name,
        js.position,
        js.timestamp,
        velocity=js.velocity,
        effort=js.effort,
        automatic_timestamp=True,
    )


def position_cartesian(cp) -> dict:
    """``prmPositionCartesianGet``."""
    return encode_pose(
        cp.T, cp.reference_frame, cp.moving_frame, cp.timestamp, automatic_timestamp=True
    )


def velocity_cartesian(cv) -> dict:
    """``prmVelocityCartesianGet``."""
    v = np.asarray(cv.twist)
    return {
        "VelocityLinear": v[:3].tolist(),
        "VelocityAngular": v[3:].tolist(),
        "ReferenceFrame": cv.reference_frame,
        "MovingFrame": cv.moving_frame,
        "Timestamp": cv.timestamp,
        "AutomaticTimestamp": True,
        "Valid": True,
    }


def operating_state(s) -> dict:
    """``prmOperatingState`` (the enum as its name)."""
    return {
        "State": s.state,
        "SubState": "",
        "IsHomed": bool(s.is_homed),
        "IsBusy": bool(s.is_busy),
        "Timestamp": s.timestamp,
        "AutomaticTimestamp": True,
        "Valid": True,
    }


READERS: dict[str, Callable[[ArmSnapshot], dict | None]] = {
    "measured_js": lambda a: state_joint(a.measured_js),
    "setpoint_js": lambda a: state_joint(a.setpoint_js),
    "measured_cp": lambda a: position_cartesian(a.measured_cp),
    "setpoint_cp": lambda a: position_cartesian(a.setpoint_cp),
    "local/measured_cp": lambda a: position_cartesian(a.local_measured_cp),
    "local/setpoint_cp": lambda a: position_cartesian(a.local_setpoint_cp),
    "measured_cv": lambda a: velocity_cartesian(a.measured_cv),
    "operating_state": lambda a: operating_state(a.operating_state),
    "jaw/measured_js": lambda a: state_joint(a.jaw_measured_js) if a.jaw_measured_js else None,
    "jaw/setpoint_js": lambda a: state_joint(a.jaw_setpoint_js) if a.jaw_setpoint_js else None,
    "gripper/measured_js": lambda a: (
        state_joint(a.gripper_measured_js) if a.gripper_measured_js else None
    ),
}


def _numbers(value: Any, what: str, n: int | None = None) -> list[float]:
    if not isinstance(value, list) or not all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in value
    ):
        raise StreamError(f"{what} must be a list of numbers, got {value!r}"[:200])
    if n is not None and len(value) != n:
        raise StreamError(f"{what} must have {n} values, got {len(value)}")
    try:
        return [float(v) for v in value]
    except OverflowError:  # an integer of hundreds of digits
        raise StreamError(f"{what}: a number is too large for a float") from None


def _goal(payload: Any, key: str = "Goal") -> Any:
    if not isinstance(payload, dict) or key not in payload:
        raise StreamError(f"expected an object with {key!r}, got {payload!r}"[:200])
    return payload[key]


def _frame(payload: Any) -> np.ndarray:
    goal = _goal(payload)
    if not isinstance(goal, dict) or "Rotation" not in goal or "Translation" not in goal:
        raise StreamError("a Cartesian goal needs 'Rotation' (3x3) and 'Translation' (3)")
    R = goal["Rotation"]
    if not isinstance(R, list) or len(R) != 3:
        raise StreamError("'Rotation' must be 3 rows of 3 numbers")
    T = np.eye(4)
    T[:3, :3] = [_numbers(row, "Rotation row", 3) for row in R]
    T[:3, 3] = _numbers(goal["Translation"], "Translation", 3)
    return T


def command_call(
    arm: str, name: str, payload: Any, dof: int | None = None
) -> tuple[str, str, tuple]:
    """``(target, method, args)`` of a write command (cisst parameter types, dvrk.md §5);
    joint vectors must have ``dof`` values when it is given (so a datagram with a bad joint
    vector is refused before any of its commands runs).

    Raises:
        StreamError: for a payload of the wrong shape.
    """
    if name in ("servo_jp", "move_jp", "servo_jr", "move_jr"):
        return arm, name, (_numbers(_goal(payload), f"{name} Goal", dof),)
    if name == "servo_jf":
        return arm, name, (_numbers(_goal(payload, "ForceTorque"), "servo_jf ForceTorque", dof),)
    if name in ("jaw/servo_jp", "jaw/move_jp"):
        return f"{arm}/jaw", name.split("/")[1], (_numbers(_goal(payload), f"{name} Goal", 1)[0],)
    if name in ("servo_cp", "move_cp"):
        return arm, name, (_frame(payload),)
    if name in ("body/servo_cf", "spatial/servo_cf"):  # prmForceCartesianSet: force, torque
        target, method = name.split("/")
        return f"{arm}/{target}", method, (_numbers(_goal(payload, "Force"), f"{name} Force", 6),)
    if name == "state_command":
        if isinstance(payload, dict):
            payload = payload.get("string", payload.get("Data"))
        if not isinstance(payload, str):
            raise StreamError(f"state_command needs a string, got {payload!r}"[:200])
        return arm, name, (payload,)
    raise StreamError(f"{name!r} has no payload conversion")


# =========================================================================== the streamer
class _Stream(asyncio.DatagramProtocol):
    def __init__(
        self, owner: UdpStreamer, config: StreamConfig, arm_type: str, dof: int | None = None
    ) -> None:
        self.owner = owner
        self.config = config
        self.dof = dof
        self.read = config.read_commands or DEFAULT_READ.get(arm_type, ("measured_js",))
        unknown = [r for r in self.read if r not in READERS]
        if unknown:
            raise ValueError(
                f"{config.arm}: unknown read commands {unknown}; known: {list(READERS)}"
            )
        self.write = set(config.write_commands or DEFAULT_WRITE.get(arm_type, ()))
        self.void = set(config.void_commands)
        self.transport: asyncio.DatagramTransport | None = None
        self.sent = 0
        self.received = 0
        self.errors = 0
        self.task: PeriodicTask | None = None

    @property
    def dest(self) -> tuple[str, int]:
        return self.config.ip, self.config.port

    def connection_made(self, transport) -> None:
        self.transport = transport

    def send(self, key: str, payload: Any, to: tuple[str, int] | None = None) -> None:
        if self.transport is None:
            return
        try:
            self.transport.sendto(codec.dumps({key: payload}).encode("ascii"), to or self.dest)
            self.sent += 1
        except OSError as e:  # e.g. nobody listening (ICMP) — keep streaming
            _log.debug("%s: send failed: %s", self.config.arm, e)

    def publish(self) -> None:
        a = self.owner.handle.snapshot().arms.get(self.config.arm)
        if a is None:
            return
        for name in self.read:
            value = READERS[name](a)
            if value is not None:
                self.send(name, value)

    def datagram_received(self, data: bytes, addr) -> None:
        self.received += 1
        arm = self.config.arm
        try:
            values = codec.loads_frames(data)
            if len(values) != 1 or not isinstance(values[0], dict) or not values[0]:
                raise StreamError("a command datagram must be one non-empty JSON object")
            calls = []
            for name, payload in values[0].items():
                if name in self.void:
                    calls.append((arm, name, ()))
                elif name in self.write:
                    calls.append(command_call(arm, name, payload, self.dof))
                else:
                    raise StreamError(
                        f"unknown command {name!r}; accepted: {sorted(self.void | self.write)}"
                    )
        except (codec.DecodeError, StreamError) as e:
            self.errors += 1
            _log.error("%s: datagram from %s:%s refused: %s", arm, addr[0], addr[1], e)
            if "error" in self.config.write_events:
                self.send("error", f"{arm}: {e}")
                if tuple(addr[:2]) != self.dest:
                    self.send("error", f"{arm}: {e}", addr[:2])
            return
        for target, method, args in calls:
            future = self.owner.handle.call(target, method, *args)
            future.add_done_callback(self._done)

    def _done(self, future) -> None:
        exc = future.exception()
        result = None if exc is not None else future.result()
        if exc is not None or (hasattr(result, "accepted") and not result.accepted):
            self.errors += 1
            _log.error("%s: %s", self.config.arm, exc or result.message)

    def error_received(self, exc) -> None:
        _log.debug("%s: %s", self.config.arm, exc)


class UdpStreamer(AsyncService):
    """Streams arms of ``handle`` as dVRK socket streamers, in its own thread and loop.

    Args:
        handle: the running simulation.
        streams: one config per arm (see :func:`default_streams`).
    """

    def __init__(self, handle: SimHandle, streams: Sequence[StreamConfig]) -> None:
        names = [s.arm for s in streams]
        if len(set(names)) != len(names):
            raise ValueError(f"one stream per arm, got {names}")
        super().__init__()
        self.handle = handle
        self.configs = tuple(streams)
        self.streams: dict[str, _Stream] = {}
        self._unsubscribe: Callable[[], None] | None = None

    thread_name = "udp-streamer"

    def start(self, timeout: float = 5.0) -> UdpStreamer:
        """Bind every stream's socket and start publishing (raises what binding raised)."""
        return super().start(timeout)

    def local_port(self, arm: str) -> int:
        """The port this arm's socket is bound to (where commands go)."""
        transport = self.streams[arm].transport
        assert transport is not None
        return transport.get_extra_info("sockname")[1]

    def stats(self) -> dict:
        return {
            a: {"sent": s.sent, "received": s.received, "errors": s.errors}
            for a, s in self.streams.items()
        }

    async def main(self) -> None:
        loop = asyncio.get_running_loop()
        snap = self.handle.snapshot()
        try:
            for cfg in self.configs:
                if cfg.arm not in snap.arms:
                    raise ValueError(f"no arm {cfg.arm!r}; arms: {sorted(snap.arms)}")
                a = snap.arms[cfg.arm]
                stream = _Stream(self, cfg, a.arm_type, len(a.measured_js.name))
                await loop.create_datagram_endpoint(
                    lambda s=stream: s, local_addr=(cfg.bind_ip, cfg.bind_port)
                )
                self.streams[cfg.arm] = stream
                stream.task = PeriodicTask(cfg.period, stream.publish)
                stream.task.start()
            self._unsubscribe = self.handle.subscribe(
                lambda src, ev, payload: loop.call_soon_threadsafe(self._event, src, ev, payload)
            )
            self.ready()
            await self.stopping.wait()
        finally:
            if self._unsubscribe is not None:
                self._unsubscribe()
            for s in self.streams.values():
                if s.task is not None:
                    await s.task.stop()
                if s.transport is not None:
                    s.transport.close()

    def _event(self, source: str, event: str, payload: Any) -> None:
        stream = self.streams.get(source)
        if stream is None or event not in stream.config.write_events:
            return
        if event == "operating_state":
            stream.send(event, operating_state(payload))
        else:
            stream.send(event, getattr(payload, "text", str(payload)))


def default_streams(arms: Sequence[str], ports: dict[str, int] | None = None) -> list[StreamConfig]:
    """Stream configs for ``arms`` with the default (or given) destination ports."""
    ports = {**DEFAULT_PORTS, **(ports or {})}
    missing = [a for a in arms if a not in ports]
    if missing:
        raise ValueError(f"no UDP port for {missing}; give one (e.g. {missing[0]}=48060)")
    return [StreamConfig(a, ports[a]) for a in arms]


def parse_ports(text: str) -> dict[str, int]:
    """``"PSM1=48051,ECM=48053"`` → ``{"PSM1": 48051, "ECM": 48053}``."""
    out = {}
    for item in filter(None, (s.strip() for s in text.split(","))):
        arm, sep, port = item.partition("=")
        if not sep or not port.isdigit():
            raise ValueError(f"bad port assignment {item!r}; expected ARM=PORT")
        out[arm] = int(port)
    return out


__all__ = ["StreamConfig", "UdpStreamer", "default_streams", "parse_ports"]
