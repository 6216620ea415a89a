"""A service that owns a thread with its own asyncio loop: :class:`AsyncService`.

The servers around a running simulation (the rosbridge server, the UDP streamer, the web
console) each run their sockets in an asyncio loop on a thread of their own, so a caller
starts them and goes on, and the 1 kHz loop never waits for them. They share this life
cycle: :meth:`AsyncService.start` returns once the subclass's :meth:`~AsyncService.main`
says it is ready (:meth:`~AsyncService.ready`) or re-raises what ``main`` raised before
(e.g. ``OSError`` for a taken port); :meth:`~AsyncService.stop` sets :attr:`stopping`, which
``main`` awaits, then joins the thread; a service still running at interpreter exit is
stopped (``atexit``). On the way out every task left in the loop is cancelled and awaited.
"""

from __future__ import annotations

import asyncio
import atexit
import concurrent.futures
import logging
import threading
from collections.abc import Coroutine

_log = logging.getLogger("davinci_sim.runtime")


class AsyncService:
    """Base of a service with its own thread and asyncio loop; see the module docstring.

    Subclasses implement ``async def main(self)``: set up, call :meth:`ready`, await
    ``self.stopping.wait()``, clean up. ``thread_name`` names the thread.
    """

    thread_name = "async-service"

    def __init__(self) -> None:
        self.loop: asyncio.AbstractEventLoop | None = None
        self.stopping: asyncio.Event | None = None
        """Set by :meth:`stop`; ``main`` awaits it (created in the service's loop)."""
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None

    async def main(self) -> None:  # pragma: no cover - subclasses implement it
        raise NotImplementedError

    # ------------------------------------------------------------ life cycle
    def start(self, timeout: float = 10.0):
        """Run :meth:`main` on the service's thread; return once it is ready.

        Raises:
            TimeoutError: if ``main`` did not call :meth:`ready` in ``timeout`` s.
            Exception: whatever ``main`` raised before it was ready.
        """
        if self._thread is not None:
            return self
        self._ready.clear()
        self._error = None
        self._thread = threading.Thread(target=self._run, name=self.thread_name, daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout):
            raise TimeoutError(f"{self.thread_name} did not start in {timeout:g} s")
        if self._error is not None:
            self._thread.join(timeout)
            self._thread = None
            raise self._error
        atexit.register(self.stop)
        return self

    def ready(self) -> None:
        """Called by :meth:`main` once the service serves: :meth:`start` returns."""
        self._ready.set()

    def stop(self, timeout: float = 10.0) -> None:
        """Tell :meth:`main` to finish and join the thread (nothing if not started)."""
        thread = self._thread
        if thread is None:
            return
        if self.loop is not None and self.stopping is not None:
            try:
                self.loop.call_soon_threadsafe(self.stopping.set)
            except RuntimeError:  # the loop has already closed
                pass
        thread.join(timeout)
        self._thread = None
        atexit.unregister(self.stop)

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def run_coroutine(self, coro: Coroutine) -> concurrent.futures.Future:
        """Run ``coro`` in the service's loop (from another thread)."""
        assert self.loop is not None, "the service is not running"
        return asyncio.run_coroutine_threadsafe(coro, self.loop)

    # ------------------------------------------------------------ the thread
    def _run(self) -> None:
        loop = asyncio.new_event_loop()
        self.loop = loop
        try:
            loop.run_until_complete(self._main_with_event())
        except BaseException as e:  # reported to start() if it happened there
            if not self._ready.is_set():
                self._error = e
                self._ready.set()
            else:
                _log.exception("%s stopped on an error", self.thread_name)
        finally:
            try:
                pending = asyncio.all_tasks(loop)
                for task in pending:
                    task.cancel()
                if pending:
                    loop.run_until_complete(asyncio.gather(*pending, return_exceptions=True))
            finally:
                loop.close()
                self.loop = None

    async def _main_with_event(self) -> None:
        self.stopping = asyncio.Event()
        await self.main()
