"""A minimal client of a viser server, as a browser would connect, for tests and benchmarks.

:class:`ViserProbe` opens viser's websocket with the server's protocol version, reports a
camera (viser counts a client as connected from its first camera message, so presets reach
it), and records every frame the server sends: when it arrived, its size on the wire, and
the types of the messages it carried. Frame layout (viser's ``_message_producer``): the
sizes of the msgpack payload before and after zstd (8 bytes each, little-endian), the
compressed payload ``{"messages": [...], ...}``, then raw binary buffers (meshes).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import msgspec
import zstandard


@dataclass(frozen=True)
class ProbeFrame:
    """One websocket frame from the server."""

    t: float
    """Arrival, ``time.perf_counter()`` s."""
    nbytes: int
    """Size on the wire, bytes."""
    types: tuple[str, ...]
    """Viser message types it carried, in order."""
    names: tuple[str | None, ...]
    """The scene node each message names (None for messages without one), in order."""
    messages: tuple[dict, ...] = ()
    """The decoded messages (arrays left as viser's placeholders for its binary buffers)."""


class ViserProbe:
    """Connect to the viser server at ``url`` (``http://host:port``) and record its frames.

    Use as a context manager, or :meth:`close` it; :attr:`frames` is safe to read at any time.
    """

    def __init__(self, url: str, *, camera_position=(3.0, 3.0, 2.0), timeout: float = 10.0):
        import viser
        from viser import _messages
        from websockets.sync.client import connect

        ws_url = url.replace("http://", "ws://", 1).replace("https://", "wss://", 1)
        self._ws = connect(
            ws_url,
            subprotocols=[f"viser-v{viser.__version__}"],
            max_size=None,
            open_timeout=timeout,
        )
        self.frames: list[ProbeFrame] = []
        self._lock = threading.Lock()
        self._closed = threading.Event()
        self._zstd = zstandard.ZstdDecompressor()
        camera = _messages.ViewerCameraMessage(
            wxyz=(1.0, 0.0, 0.0, 0.0),
            position=tuple(map(float, camera_position)),
            fov=1.0,
            near=0.01,
            far=100.0,
            image_height=480,
            image_width=640,
            look_at=(0.0, 0.0, 0.0),
            up_direction=(0.0, 0.0, 1.0),
        )
        self._ws.send(msgspec.msgpack.encode(camera.as_serializable_dict()))
        self._thread = threading.Thread(target=self._receive, name="viser-probe", daemon=True)
        self._thread.start()

    def _decode(self, raw: bytes, t: float) -> ProbeFrame:
        size = int.from_bytes(raw[0:8], "little")
        compressed = int.from_bytes(raw[8:16], "little")
        inner = self._zstd.decompress(raw[16 : 16 + compressed], max_output_size=size)
        messages = msgspec.msgpack.decode(inner)["messages"]
        types = tuple(m.get("type", "?") for m in messages)
        names = tuple(m.get("name") if isinstance(m.get("name"), str) else None for m in messages)
        return ProbeFrame(t, len(raw), types, names, tuple(messages))

    def _receive(self) -> None:
        while not self._closed.is_set():
            try:
                raw = self._ws.recv(timeout=0.1)
            except TimeoutError:
                continue
            except Exception:  # connection closed (server stopped or close())
                return
            frame = self._decode(raw, time.perf_counter())
            with self._lock:
                self.frames.append(frame)

    def send(self, message) -> None:
        """Send a viser message (e.g. ``GuiUpdateMessage``) as the page would."""
        self._ws.send(msgspec.msgpack.encode(message.as_serializable_dict()))

    def gui_uuid(self, label: str) -> str | None:
        """The uuid of the GUI element labelled ``label`` the server sent, None if none."""
        for frame in self.received():
            for m in frame.messages:
                if m.get("type", "").startswith("Gui") and m.get("props", {}).get("label") == label:
                    return m.get("uuid")
        return None

    def received(self) -> list[ProbeFrame]:
        """A copy of the frames so far."""
        with self._lock:
            return list(self.frames)

    def wait_for(self, predicate, timeout: float = 10.0) -> bool:
        """Wait until ``predicate(frames)`` is true (polling); False on timeout."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if predicate(self.received()):
                return True
            time.sleep(0.01)
        return predicate(self.received())

    def close(self) -> None:
        self._closed.set()
        self._ws.close()
        self._thread.join()

    def __enter__(self) -> ViserProbe:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
