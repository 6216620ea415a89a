"""The one interface the ``crtk``/``dvrk`` compatibility layer talks through, and its two ends.

:class:`RosbridgeClient` speaks the rosbridge v2 protocol (rosbridge.md §1: ``advertise``,
``publish``, ``subscribe``, ``call_service``; messages as JSON objects, the dialect of the
server) over a :class:`Connection`, of which there are two:

* :class:`WebSocketConnection` — to a rosbridge server at ``ws://host:port``: the simulator's
  built-in one (``davinci-sim serve``, another process or machine) or a real
  ``rosbridge_server`` in front of a dVRK;
* :class:`~davinci_sim.compat.inprocess.InProcessConnection` — to the simulator's own
  bridge and dVRK nodes running in this process, without a socket or a port
  (:class:`~davinci_sim.compat.inprocess.InProcessBridge`).

Both carry the same text frames, so a script sees the same topics, validation, refusals and
latching either way; only the wire differs. Callbacks run in the connection's reader thread:
they must be quick (the crtk layer stores the message and sets an event).
"""

from __future__ import annotations

import itertools
import json
import logging
import threading
from collections.abc import Callable
from concurrent.futures import Future
from typing import Protocol

_log = logging.getLogger("davinci_sim.compat")

MessageCallback = Callable[[dict], None]


class TransportError(ConnectionError):
    """The connection to the simulation could not be made or was lost."""


class Connection(Protocol):
    """A text-frame pipe to a rosbridge server."""

    def start(self, on_frame: Callable[[str], None], on_close: Callable[[], None]) -> None:
        """Begin delivering incoming frames (in one reader thread, in order)."""

    def send(self, text: str) -> None: ...

    def close(self) -> None: ...


class WebSocketConnection:
    """A websocket to ``url`` (``ws://host:port``), read by a daemon thread."""

    def __init__(self, url: str, *, open_timeout: float = 10.0) -> None:
        from websockets.sync.client import connect

        self.url = url
        try:
            self._ws = connect(url, open_timeout=open_timeout, max_size=None,
                               compression=None, close_timeout=1)  # fmt: skip
        except (OSError, TimeoutError) as e:
            raise TransportError(f"cannot connect to the rosbridge server at {url}: {e}") from e
        except Exception as e:  # websockets' handshake errors (InvalidURI, InvalidHandshake …)
            raise TransportError(f"cannot connect to the rosbridge server at {url}: {e}") from e
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None

    def start(self, on_frame: Callable[[str], None], on_close: Callable[[], None]) -> None:
        def read() -> None:
            try:
                for frame in self._ws:
                    on_frame(frame if isinstance(frame, str) else frame.decode("utf-8"))
            except Exception as e:  # closed: the client's waits end
                _log.debug("rosbridge connection ended: %s", e)
            finally:
                on_close()

        self._thread = threading.Thread(target=read, name="crtk-rosbridge", daemon=True)
        self._thread.start()

    def send(self, text: str) -> None:
        try:
            with self._lock:
                self._ws.send(text)
        except Exception as e:
            raise TransportError(f"the connection to {self.url} is closed: {e}") from e

    def close(self) -> None:
        try:
            self._ws.close()
        except Exception:  # already closed
            pass
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(2.0)


class RosbridgeClient:
    """Topics and services of a rosbridge server over ``connection``.

    Subscriptions to one topic share one ``subscribe`` op; a topic is advertised once, on
    its first :meth:`publish`. Service calls wait for the response (``timeout`` s).
    """

    def __init__(self, connection: Connection, *, description: str = "") -> None:
        self.connection = connection
        self.description = description
        self._ids = itertools.count(1)
        self._lock = threading.Lock()
        self._callbacks: dict[str, list[MessageCallback]] = {}
        self._types: dict[str, str] = {}
        self._advertised: set[str] = set()
        self._calls: dict[str, Future] = {}
        self.closed = threading.Event()
        self.close_callbacks: list[Callable[[], None]] = []
        self._ros_version: int | None = None
        self.status: list[str] = []
        """Status texts (warnings, errors) the server sent, newest last (at most 100)."""
        connection.start(self._on_frame, self._on_close)

    # ------------------------------------------------------------ outgoing
    def _send(self, op: dict) -> None:
        if self.closed.is_set():
            raise TransportError("the connection to the simulation is closed")
        self.connection.send(json.dumps(op))

    def subscribe(self, topic: str, type_name: str, callback: MessageCallback,
                  queue_length: int = 0) -> None:  # fmt: skip
        """Call ``callback(msg)`` for each message of ``topic``. ``queue_length`` > 0 bounds
        the server's queue for this client (the oldest dropped: 1 for a value of which only
        the newest matters); 0: the server's default (the first subscription decides)."""
        with self._lock:
            first = topic not in self._callbacks
            self._callbacks.setdefault(topic, []).append(callback)
            self._types.setdefault(topic, type_name)
        if first:
            op = {"op": "subscribe", "topic": topic, "type": type_name,
                  "id": f"subscribe:{topic}:{next(self._ids)}"}  # fmt: skip
            if queue_length > 0:
                op["queue_length"] = int(queue_length)
            self._send(op)

    def publish(self, topic: str, type_name: str, msg: dict) -> None:
        with self._lock:
            first = topic not in self._advertised
            self._advertised.add(topic)
        if first:
            self._send({"op": "advertise", "topic": topic, "type": type_name,
                        "id": f"advertise:{topic}:{next(self._ids)}"})  # fmt: skip
        self._send({"op": "publish", "topic": topic, "msg": msg})

    def call_service(self, service: str, args: dict, *, type_name: str | None = None,
                     timeout: float = 10.0) -> dict:  # fmt: skip
        """The response's values.

        Raises:
            TimeoutError: no response in ``timeout`` s.
            RuntimeError: the server answered ``result: false`` (its text).
        """
        call_id = f"call_service:{service}:{next(self._ids)}"
        future: Future = Future()
        with self._lock:
            self._calls[call_id] = future
        op = {"op": "call_service", "service": service, "args": args, "id": call_id}
        if type_name:
            op["type"] = type_name
        try:
            self._send(op)
            return future.result(timeout)
        except TimeoutError:
            raise TimeoutError(f"no response from {service} within {timeout:g} s") from None
        finally:
            with self._lock:
                self._calls.pop(call_id, None)

    def ros_version(self) -> int:
        """The server's ROS dialect (1 or 2), asked once from ``/rosapi/get_ros_version``; a
        server that does not answer it is taken for a ROS 1 one (whose older rosapi lacks
        it)."""
        if self._ros_version is None:
            try:
                values = self.call_service("/rosapi/get_ros_version", {}, timeout=5.0)
                self._ros_version = 1 if int(values.get("version", 2)) == 1 else 2
            except (RuntimeError, TimeoutError, TransportError, ValueError):
                self._ros_version = 1
        return self._ros_version

    def close(self) -> None:
        if not self.closed.is_set():
            self.connection.close()
            self._on_close()

    # ------------------------------------------------------------ incoming
    def _on_frame(self, text: str) -> None:
        try:
            op = json.loads(text)
        except ValueError:
            _log.warning("rosbridge: a frame that is not JSON: %.100s", text)
            return
        kind = op.get("op")
        if kind == "publish":
            for callback in list(self._callbacks.get(op.get("topic"), ())):
                try:
                    callback(op.get("msg") or {})
                except Exception:  # a callback's bug must not stop the reader
                    _log.exception("callback of %s failed", op.get("topic"))
        elif kind == "service_response":
            with self._lock:
                future = self._calls.get(op.get("id"))
            if future is not None and not future.done():
                if op.get("result", True):
                    future.set_result(op.get("values") or {})
                else:
                    future.set_exception(RuntimeError(f"{op.get('service')}: {op.get('values')}"))
        elif kind == "status":
            text = f"{op.get('level', '')}: {op.get('msg', '')}"
            self.status = [*self.status[-99:], text]
            _log.warning("rosbridge %s", text)

    def _on_close(self) -> None:
        if self.closed.is_set():
            return
        self.closed.set()
        with self._lock:
            calls = list(self._calls.values())
        for future in calls:
            if not future.done():
                future.set_exception(TransportError("the connection to the simulation closed"))
        for callback in list(self.close_callbacks):
            try:
                callback()
            except Exception:
                _log.exception("close callback failed")
