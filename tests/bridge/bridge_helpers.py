"""Helpers of the bridge tests (imported by the tests and by conftest.py)."""

import contextlib
import json
import threading
import time
from types import SimpleNamespace

from websockets.sync.client import connect

#: Longest wait for a roslibpy client to connect, s: a deadline for a failure, generous for a
#: busy machine (``make test`` runs two workers); no test asserts how fast it connects.
ROS_CONNECT_TIMEOUT = 60.0

#: The first try's wait, s (``ros_client``): a client that connects at all does so in well
#: under a second here, even under ``make test``'s load; the one that did not connect (a few
#: runs in ten) never did, and a fresh one then connected at once: no point waiting 60 s.
ROS_FIRST_TRY = 15.0


#: The least time a wait for a condition gives it, s: the deadline only ends a failing test
#: (a busy machine must not fail a passing one); no test asserts how fast a condition comes.
FAIL_AFTER = 30.0

#: Longest wait for ``davinci-sim serve`` to come up, s: a failure deadline for a start that
#: hangs (a start that raises fails at once with its error). A clean clone compiles its
#: kernels on first use: 16 s for one ``serve`` on an idle 2-core machine, more under load.
START_DEADLINE = 180.0


def ros_client(port: int):
    """A roslibpy client connected to the server on 127.0.0.1:``port``.

    Clients of one test module did not connect in ``ROS_CONNECT_TIMEOUT`` in three CI runs
    and once in a clean clone here, with the server answering handshakes and roslibpy's
    reactor running. roslibpy queues a client's connect in the one reactor thread of the
    process behind every send queued before it, and a clean clone's log showed 20,194 sends
    to closed connections drained (each raising and logged) while the client waited: the
    backlog of earlier tests' streams. So the client waits first for that queue to drain
    (at most ``ROS_CONNECT_TIMEOUT``); one that does not connect in ``ROS_FIRST_TRY`` gets
    one fresh try of ``ROS_CONNECT_TIMEOUT``, with a warning of the facts (the server's own
    handshake, the reactor, the queue); a second failure raises with them."""
    import warnings

    import roslibpy
    from twisted.internet import reactor

    from davinci_sim.bridge.client_mode import send_backlog

    wait_for(lambda: send_backlog() < 100, timeout=ROS_CONNECT_TIMEOUT, period=0.05)
    for attempt, timeout in ((1, ROS_FIRST_TRY), (2, ROS_CONNECT_TIMEOUT)):
        ros = roslibpy.Ros("127.0.0.1", port)
        try:
            ros.run(timeout)
            return ros
        except roslibpy.core.RosTimeoutError:
            try:
                with connect(f"ws://127.0.0.1:{port}", open_timeout=FAIL_AFTER):
                    server = "the server answers a handshake of its own"
            except Exception as e:
                server = f"the server does not answer a handshake ({e!r})"
            threads = sorted(t.name for t in threading.enumerate())
            retries = getattr(ros.factory, "retries", "?")
            # (roslibpy's own fields, for the diagnosis: the TCP connection, and whether the
            # handshake ended: a protocol set with no "ready" seen would be a missed event)
            tcp = getattr(getattr(ros.factory, "connector", None), "state", "?")
            opened = getattr(ros.factory, "_proto", None) is not None
            facts = (f"roslibpy did not connect to port {port} in {timeout} s: "
                     f"{server}; connector={tcp}, handshake done={opened}, "
                     f"reactor running={reactor.running}, retries={retries}, "
                     f"queued reactor calls={send_backlog()}, threads={threads}")  # fmt: skip
            ros.factory.stopTrying()  # (the failed client would go on reconnecting)
            if attempt == 2:
                raise roslibpy.core.RosTimeoutError(facts) from None
            warnings.warn(facts + "; trying a fresh client", stacklevel=2)
    raise AssertionError("unreachable")


def wait_for(predicate, timeout=5.0, period=0.01):
    """Poll ``predicate`` until true or ``max(timeout, FAIL_AFTER)`` s pass; returns its last
    value (true as soon as the condition holds)."""
    end = time.monotonic() + max(timeout, FAIL_AFTER)
    while True:
        value = predicate()
        if value or time.monotonic() > end:
            return value
        time.sleep(period)


class RawClient:
    """A bare websocket client speaking rosbridge JSON, to send what roslibpy cannot."""

    def __init__(self, server, level="info"):
        self._cm = connect(server.url, compression=None, max_size=None)
        self.ws = self._cm.__enter__()
        if level:
            self.send({"op": "set_level", "level": level})

    def send(self, obj):
        self.ws.send(obj if isinstance(obj, str | bytes) else json.dumps(obj))

    def recv(self, timeout=5.0):
        data = self.ws.recv(timeout)
        return (
            data if isinstance(data, bytes) and data[:1] not in (b"{", b"[") else json.loads(data)
        )

    def recv_until(self, predicate, timeout=5.0):
        """Messages until one satisfies ``predicate``; returns it (TimeoutError if none)."""
        end = time.monotonic() + timeout
        while True:
            left = end - time.monotonic()
            if left <= 0:
                raise TimeoutError("no matching message")
            msg = self.recv(left)
            if predicate(msg):
                return msg

    def status(self, timeout=5.0):
        return self.recv_until(lambda m: isinstance(m, dict) and m.get("op") == "status", timeout)

    def call(self, service, args=None, id="c1", timeout=5.0):
        self.send({"op": "call_service", "service": service, "args": args or {}, "id": id})
        return self.recv_until(
            lambda m: (
                isinstance(m, dict) and m.get("op") == "service_response" and m.get("id") == id
            ),
            timeout,
        )

    def close(self):
        self._cm.__exit__(None, None, None)


def enable_and_home(handle, arm="PSM1", timeout=10.0):
    handle.call(arm, "state_command", "enable").result(5)
    handle.call(arm, "state_command", "home").result(5)
    ok = wait_for(
        lambda: (s := handle.snapshot().arms[arm].operating_state).is_homed and not s.is_busy,
        timeout,
    )
    assert ok, f"{arm} did not home"


@contextlib.contextmanager
def serving(options):
    """``davinci-sim serve`` with ``options`` in a thread, as a user runs it. Yields its
    ``url``, ``port`` and what ``serve`` returned once stopped (``result["done"]``); on exit
    stops it and checks that ``serve`` returned. Fails if it is not up within
    ``START_DEADLINE``."""
    from davinci_sim.bridge.app import serve

    ready, stop = {}, threading.Event()

    def run():
        try:
            ready.update(done=serve(options, stop=stop, on_ready=ready.update))
        except BaseException as e:  # (the test fails at once with it, not at the deadline)
            ready["error"] = e
            raise

    thread = threading.Thread(target=run)
    thread.start()
    server = SimpleNamespace(url=None, port=None, result=ready)
    try:
        assert wait_for(lambda: "url" in ready or "error" in ready, START_DEADLINE), (
            "serve did not start"
        )
        assert "error" not in ready, f"serve failed to start: {ready['error']!r}"
        server.url = ready["url"]
        server.port = int(ready["url"].rsplit(":", 1)[1])
        yield server
    finally:
        stop.set()
        thread.join(30)
    assert "done" in ready, "serve did not return"
