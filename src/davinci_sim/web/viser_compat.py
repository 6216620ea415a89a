"""What the bedside view relies on beyond viser's public API, in one place (viser 1.1).

Each function checks the internals it uses and does nothing (or returns None) when they
are not as expected, so a newer viser degrades to the public API instead of failing:

* :func:`quiet`: viser prints a banner and "Server stopped" whatever ``verbose`` says;
* :func:`widen_message_window`: viser sends at most 128 messages per websocket frame, which
  splits a full-scene pose update (two messages per moving body) in two frames;
* :func:`pose_queue`: a pose setter's own checks (``np.allclose`` and casts per call) are
  most of an update's time; queueing the same messages directly avoids them;
* :func:`refuse_share_url`: the page's "share" button makes the server open a public
  tunnel through share.viser.studio;
* :func:`shutdown_executor`: ``ViserServer.stop`` leaves its thread pool to finish alone.
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Callable, Iterator

import numpy as np


@contextlib.contextmanager
def quiet() -> Iterator[None]:
    """Swallow what viser prints to stdout meanwhile (the process's stdout, briefly)."""
    with contextlib.redirect_stdout(io.StringIO()):
        yield


def widen_message_window(server, messages: int) -> bool:
    """Let a frame carry ``messages`` messages; True if the setting exists and was set."""
    buffer = getattr(getattr(server, "_websock_server", None), "_broadcast_buffer", None)
    if buffer is None or not isinstance(getattr(buffer, "max_window_size", None), int):
        return False
    buffer.max_window_size = max(buffer.max_window_size, int(messages))
    return True


def pose_queue(server, node) -> Callable[[object, tuple, tuple], None] | None:
    """``send(node, position, wxyz)``: queue a scene node's new pose as its setters would
    (the handle's stored pose updated, one position and one orientation message, replayed
    to browsers that connect later), without their checks; None if viser's internals
    differ (then use ``node.position = ...; node.wxyz = ...``)."""
    try:
        from viser import _messages

        Position, Orientation = _messages.SetPositionMessage, _messages.SetOrientationMessage
    except (ImportError, AttributeError):
        return None
    queue = getattr(getattr(server, "scene", None), "_queue_scene_message", None)
    impl = getattr(node, "_impl", None)
    if not (
        callable(queue)
        and isinstance(getattr(impl, "position", None), np.ndarray)
        and isinstance(getattr(impl, "wxyz", None), np.ndarray)
        and isinstance(getattr(impl, "name", None), str)
    ):
        return None

    def send(node, position: tuple, wxyz: tuple) -> None:
        impl = node._impl
        impl.position[:] = position
        impl.wxyz[:] = wxyz
        queue(Position(impl.name, position))
        queue(Orientation(impl.name, wxyz))

    return send


def refuse_share_url(server, on_request: Callable[[], None]) -> None:
    """Hide the page's share button and answer its request with ``on_request()`` instead
    of a tunnel (viser dispatches the request to ``server.request_share_url``)."""
    server.gui.configure_theme(show_logo=False, show_share_button=False)

    def refuse(*args, **kwargs) -> None:
        on_request()

    server.request_share_url = refuse


def shutdown_executor(server) -> None:
    """Wait for the stopped server's callback threads to end."""
    executor = getattr(server, "_thread_executor", None)
    if executor is not None:
        executor.shutdown(wait=True)
