"""One client connection: frames in, ops to the bridge, bounded queues out.

Incoming frames are checked for size, decoded (strict JSON, several objects per frame,
fragments reassembled) and parsed into typed ops; anything wrong is reported with
:meth:`Session.report` (log, ``/rosout``, and a ``status`` op if the client asked for them
with ``set_level``, rosbridge.md §1.2) and the connection carries on.

Outgoing messages wait in bounded queues: one per subscription (``queue_length`` or the
server default; the oldest is dropped when full) and one for replies. A slow client only
loses its own oldest messages and never blocks the loop or other clients (rosbridge.md §5
"Slow consumers"). A writer task sends the queued messages in the order they were published,
across topics: a client that sees a move end on ``operating_state`` has by then been sent
every ``measured_js`` published before it, however far behind it reads.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import time
from collections import deque
from typing import TYPE_CHECKING, Any

from websockets.exceptions import ConnectionClosed

from davinci_sim.bridge.rosbridge import codec
from davinci_sim.bridge.rosbridge.auth import check_auth
from davinci_sim.bridge.rosbridge.graph import OutMessage, Subscription
from davinci_sim.bridge.rosbridge.protocol import (
    Auth,
    Fragment,
    Id,
    OpError,
    SetLevel,
    StatusOut,
    parse_op,
    to_wire,
)

if TYPE_CHECKING:
    from davinci_sim.bridge.rosbridge.core import Bridge

_log = logging.getLogger("davinci_sim.bridge")

LEVELS = {"none": 0, "error": 1, "warning": 2, "info": 3}
_session_ids = itertools.count(1)


#: Longest text a problem report carries (log, ``/rosout``, ``status``), characters: reports
#: quote what the client sent, which may be megabytes.
MAX_REPORT = 500
#: All clients together may hold this many times ``max_message_size`` bytes of unfinished
#: fragmented messages.
MAX_PENDING_CLIENTS = 4


def shorten(text: str, limit: int = MAX_REPORT) -> str:
    """``text``, or its start and end with how many characters were left out between."""
    if len(text) <= limit:
        return text
    head, tail = text[: limit - 120], text[-80:]
    return f"{head} … ({len(text) - len(head) - len(tail)} characters left out) … {tail}"


class Session:
    """A connected client (one websocket)."""

    def __init__(self, bridge: Bridge, ws: Any) -> None:
        self.bridge = bridge
        self.ws = ws
        self.number = next(_session_ids)
        try:
            host, port = ws.remote_address[:2]
            self.peer = f"{host}:{port}"
        except Exception:
            self.peer = "?"
        self.name = f"client {self.number} ({self.peer})"
        cfg = bridge.config
        self.status_level = 0  # no status ops unless the client asks (rosbridge.md §6.4)
        self.fragment_size: int | None = None
        self.authenticated = cfg.auth_token is None
        self.auth_failures = 0
        self.subscriptions: dict[str, Subscription] = {}
        self.advertised: dict[str, set] = {}
        self.services: set[str] = set()
        self.actions: set[str] = set()
        self._control: deque[str | bytes] = deque(maxlen=cfg.control_queue_length)
        self._ready: set[Subscription] = set()
        self._published = itertools.count()
        """Order of the messages queued for this client, across subscriptions."""
        self._frames: deque[str | bytes] = deque()
        self._wake = asyncio.Event()
        self._fragments: dict[Any, tuple[float, dict[int, str], int]] = {}
        self._frag_counter = itertools.count(1)
        self.dropped = 0
        self.control_dropped = 0
        self.received = 0
        self.sent = 0
        self.closed = False
        self._close_after: tuple[int, str] | None = None
        """(code, reason): close once the queued replies are sent (a refused client)."""

    # ================================================================ incoming
    async def run(self) -> None:
        """Read until the client goes; the writer runs alongside."""
        writer = asyncio.ensure_future(self._write_loop())
        try:
            async for frame in self.ws:
                self.received += 1
                try:
                    self.handle_frame(frame)
                except Exception:  # a bug must not take the connection down
                    _log.exception("%s: internal error while handling a message", self.name)
                    self.report("error", "internal error while handling the message")
        except ConnectionClosed:
            pass
        finally:
            self.closed = True
            writer.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await writer

    def handle_frame(self, frame: str | bytes) -> None:
        if self._close_after is not None:
            return  # refused: the status is on its way, then the connection closes
        limit = self.bridge.config.max_message_size
        size = len(frame)
        if isinstance(frame, str) and size * 4 > limit:
            size = len(frame.encode("utf-8"))
        if size > limit:
            self.report(
                "error",
                f"message of {size} bytes exceeds the limit of {limit} bytes; it was dropped",
            )
            return
        try:
            values = codec.loads_frames(frame)
        except codec.DecodeError as e:
            self.report("error", f"bad message: {e}")
            return
        for value in values:
            self.handle_value(value)

    def handle_value(self, value: Any) -> None:
        if isinstance(value, dict):
            fs = value.get("fragment_size")
            # Any message carrying fragment_size sets the client's outgoing fragment size;
            # huge values (ROS# sends 2**31-1) mean "no fragments" (rosbridge.md §1.1, §6.4).
            if isinstance(fs, int) and not isinstance(fs, bool) and fs > 0:
                limit = self.bridge.config.max_message_size
                self.fragment_size = fs if fs < limit else None
        try:
            op = parse_op(value)
        except OpError as e:
            if not self.authenticated:
                self._refuse(str(e), e.id)
            else:
                self.report("error", str(e), e.id)
            return
        if not self.authenticated and not isinstance(op, Auth | SetLevel):
            first = '{"op": "auth", "mac": "<token>"}'
            self._refuse(f"{op.op}: missing token: send {first} first", _id(op))
            return
        if isinstance(op, Auth):
            self._auth(op)
        elif isinstance(op, SetLevel):
            if op.level not in LEVELS:
                self.report("error", f"set_level: level must be one of {list(LEVELS)}", op.id)
            else:
                self.status_level = LEVELS[op.level]
        elif isinstance(op, Fragment):
            self._fragment(op)
        else:
            self.bridge.handle_op(self, op)

    def _auth(self, op: Auth) -> None:
        token = self.bridge.config.auth_token
        if token is None:
            return  # rosbridge ignores auth when authentication is off
        ok, why = check_auth(token, op)
        if ok:
            self.authenticated = True
            _log.info("%s: authenticated", self.name)
            return
        self.auth_failures += 1
        self._refuse(why)

    def _refuse(self, why: str, id: Id = None) -> None:
        """Refuse an unauthenticated client: a ``status`` op at level error saying why (sent
        whatever ``set_level`` asked: without it the client would only see its calls time
        out), then close the connection (code 1008, policy violation), as rosbridge's ROS 1
        server closes a client that does not authenticate."""
        self.report("error", why, id, always=True)
        self._close_after = (1008, shorten(f"authentication failed: {why}", 120))
        self._wake.set()

    def _fragment(self, op: Fragment) -> None:
        cfg = self.bridge.config
        now = time.monotonic()
        for key in [
            k for k, (t0, _, _) in self._fragments.items() if now - t0 > cfg.fragment_timeout
        ]:
            del self._fragments[key]
        total = int(op.total)
        if total < 1 or not 0 <= op.num < total:
            self.report("error", f"fragment: num {op.num} / total {op.total} are inconsistent")
            return
        t0, parts, size = self._fragments.get(op.id, (now, {}, 0))
        if op.num not in parts:
            size += len(op.data)
        parts[op.num] = op.data
        if size > cfg.max_message_size:
            del self._fragments[op.id]
            self.report(
                "error",
                f"fragmented message {op.id!r} exceeds the limit of {cfg.max_message_size} bytes",
            )
            return
        if len(parts) < total:
            self._fragments[op.id] = (t0, parts, size)
            self._bound_fragments(op.id)
            return
        self._fragments.pop(op.id, None)
        self.handle_frame("".join(parts[i] for i in range(total)))

    @property
    def pending_fragment_bytes(self) -> int:
        """Bytes of the partial fragmented messages this client has sent."""
        return sum(size for _, _, size in self._fragments.values())

    def _bound_fragments(self, newest) -> None:
        """Drop the oldest partial messages while this client holds more than 100 of them or
        more than ``max_message_size`` bytes of them, or all clients together more than
        ``MAX_PENDING_CLIENTS`` times that: a client cannot grow the server's memory by
        starting many large fragmented messages (each alone is within the limit)."""
        limit = self.bridge.config.max_message_size
        everyone = sum(s.pending_fragment_bytes for s in self.bridge.sessions if s is not self)

        def over() -> bool:
            mine = self.pending_fragment_bytes
            return (
                len(self._fragments) > 100
                or mine > limit
                or (mine + everyone > MAX_PENDING_CLIENTS * limit)
            )

        while self._fragments and over():
            oldest = min(self._fragments, key=lambda k: self._fragments[k][0])
            del self._fragments[oldest]
            self.report("error", f"fragmented message {oldest!r} dropped: too many bytes "
                        "of unfinished fragmented messages")  # fmt: skip
            if oldest == newest:
                break

    # ================================================================ reporting
    def report(self, level: str, text: str, id: Id = None, *, always: bool = False) -> None:
        """A problem with what this client sent: log, ``/rosout``, and ``status`` if asked
        (``always``: whatever the client asked). A long text (one that echoes a huge bad
        value) is cut to :data:`MAX_REPORT` characters with the number of characters left
        out, everywhere it goes."""
        text = shorten(text)
        full = f"{self.name}: {text}"
        _log.log(logging.ERROR if level == "error" else logging.WARNING, full)
        self.bridge.rosout(level, full)
        if always or LEVELS.get(level, 3) <= self.status_level:
            self.send_op(StatusOut(level, text, id))

    # ================================================================ outgoing
    def send_op(self, op: Any) -> None:
        """Queue a reply op (service response, status, action op …)."""
        if self.closed:
            return
        self.send_text(codec.dumps(to_wire(op)))

    def send_text(self, text: str) -> None:
        frames = self._fragment_text(text)
        if len(self._control) + len(frames) > (self._control.maxlen or 0):
            self.control_dropped += len(frames)
        self._control.extend(frames)
        self._wake.set()

    def _fragment_text(self, text: str) -> list[str]:
        size = self.fragment_size
        if size is None or len(text) <= size:
            return [text]
        frag_id = f"fragment:{next(self._frag_counter)}"
        return [codec.dumps(f) for f in codec.fragments(text, size, frag_id)]

    def enqueue(self, sub: Subscription, out: OutMessage) -> None:
        """Queue a published message for ``sub`` (drops the oldest when full)."""
        if sub.throttle > 0.0 and sub.queue_length == 0:
            now = time.monotonic()
            if now - sub.last_accept < sub.throttle:
                return  # throttled: rosbridge drops it (rosbridge.md §1.3)
            sub.last_accept = now
        q = sub.queue
        if len(q) == q.maxlen:
            sub.dropped += 1
            self.dropped += 1
        q.append((next(self._published), out))
        if not sub.in_ready:
            sub.in_ready = True
            self._ready.add(sub)
        self._wake.set()

    def _encode(self, sub: Subscription, out: OutMessage) -> list[str | bytes]:
        comp = sub.compression
        if comp in ("cbor", "cbor-raw"):
            return [out.cbor()]
        data = out.png() if comp == "png" else out.json()
        size = sub.fragment_size or self.fragment_size
        if size is None or len(data) <= size:
            return [data]
        frag_id = f"fragment:{next(self._frag_counter)}"
        return [codec.dumps(f) for f in codec.fragments(data.decode("ascii"), size, frag_id)]

    def _next_frame(self) -> str | bytes | None:
        if self._control:
            return self._control.popleft()
        if self._frames:
            return self._frames.popleft()
        # The oldest message queued of a subscription that may send now (a throttled
        # subscription's next message waits for its time).
        now = time.monotonic()
        first: Subscription | None = None
        for sub in list(self._ready):
            if sub.closed or not sub.queue:
                sub.in_ready = False
                self._ready.discard(sub)
            elif not (sub.queue_length and sub.throttle and now < sub.next_send) and (
                first is None or sub.queue[0][0] < first.queue[0][0]
            ):
                first = sub
        if first is None:
            return None
        out = first.queue.popleft()[1]
        first.next_send = now + first.throttle
        if not first.queue:
            first.in_ready = False
            self._ready.discard(first)
        frames = self._encode(first, out)
        self._frames.extend(frames[1:])
        return frames[0]

    def _next_delay(self) -> float | None:
        waits = [s.next_send for s in self._ready if s.queue and not s.closed]
        if not waits:
            return None
        return max(0.0, min(waits) - time.monotonic())

    async def _write_loop(self) -> None:
        ws = self.ws
        try:
            while True:
                self._wake.clear()
                if self._close_after is not None and not self._control:
                    await ws.close(*self._close_after)
                    return
                frame = self._next_frame()
                if frame is None:
                    delay = self._next_delay()
                    if delay is None:
                        await self._wake.wait()
                    else:
                        with contextlib.suppress(TimeoutError):
                            await asyncio.wait_for(self._wake.wait(), delay)
                    continue
                if isinstance(frame, bytes) and frame[:1] in (b"{", b"["):
                    await ws.send(frame, text=True)
                else:
                    await ws.send(frame)
                self.sent += 1
        except ConnectionClosed:
            pass

    # ================================================================ info
    def stats(self) -> dict:
        return {
            "peer": self.peer,
            "received": self.received,
            "sent": self.sent,
            "dropped": self.dropped,
            "control_dropped": self.control_dropped,
            "control_queued": len(self._control),
            "subscriptions": {
                name: {"queued": len(s.queue), "dropped": s.dropped, "maxlen": s.queue.maxlen}
                for name, s in self.subscriptions.items()
            },
        }

    def __repr__(self) -> str:
        return f"<Session {self.name}>"


def _id(op: Any) -> Id:
    return getattr(op, "id", None)
