"""``serve`` in a thread for the browser tests: started, its ``info`` once the web console
is up, stopped at the end."""

from __future__ import annotations

import threading
import time
from contextlib import contextmanager

from davinci_sim.bridge.app import serve


@contextmanager
def serving(options, parts, start_timeout: float = 120.0):
    """``serve(options, parts)`` in a thread; yields its ready ``info`` (``info["web"]``:
    the page's URL). Fails if the web console is not up within ``start_timeout`` s."""
    info: dict = {}
    stop = threading.Event()
    thread = threading.Thread(
        target=lambda: info.update(
            done=serve(options, stop=stop, on_ready=info.update, parts=parts)
        )  # fmt: skip
    )
    thread.start()
    end = time.monotonic() + start_timeout
    while "web" not in info and thread.is_alive() and time.monotonic() < end:
        time.sleep(0.1)
    try:
        assert "web" in info, "serve did not start the web console"
        yield info
    finally:
        stop.set()
        thread.join(60)
    assert "done" in info, "serve did not stop"
