"""The web console's server: the page, its websocket, the views streamed to it, its commands.

:class:`WebConsole` serves the page (``web/static``) over HTTP and one websocket per page
(``/ws``) from its own thread and asyncio loop; it never touches the simulation, only its
:class:`~davinci_sim.sim.handle.SimHandle` (snapshots, calls), so the 1 kHz loop, in a
thread or its own process, is never waited on. What it streams to every page:

- the page's state (:func:`~davinci_sim.web.view.console_view`) at ``state_rate``;
- the endoscope, in one of two ways, as each page asks (``view``'s ``source``):

  * ``page``: the page draws it with three.js (``static/endoscope.js``) from the scene
    (:func:`~davinci_sim.web.endoscope_stream.scene_message`, once) and the bodies', cameras'
    and lights' poses of each new snapshot (binary pose messages,
    :class:`~davinci_sim.web.endoscope_stream.PoseStream`, up to ``pose_rate``); offered
    when the console has the system's model and three.js is installed
    (:mod:`davinci_sim.web.vendor`, served at ``/vendor/``);
  * ``server``: JPEG pairs, binary messages (:data:`FRAME_HEADER`, then the left and right
    JPEG; the right one only while some page shows both eyes, else empty), from the one
    render pipeline (``System.frames()``), each pair encoded once for all pages; asked from
    the pipeline only while a page shows them (the render process then rests);
- each finished repetition's row, tagged with the trainee's name (``rows``), also offered
  as CSV at ``/results.csv``; with the trainee records, the trainee's learning curves at
  ``/records/curve.png``.

A page sends the commands of :mod:`davinci_sim.web.protocol`; they are checked there before
anything is called, and a refused one comes back as an ``error`` message to that page only.
Any number of pages watch; one operates at a time (``control``): only the operator's
commands act, and releasing control or closing the page lets the hand go. Every page sends
as fast as the network takes it: a slow page gets the newest state and frame, not a
backlog.

Size: over 500 lines — the server is one concern (the page's connection: HTTP, socket,
sessions, arbitration, streaming, command dispatch); split it when a second page type comes.
"""

from __future__ import annotations

import asyncio
import csv
import io
import ipaddress
import itertools
import json
import logging
import math
import struct
import time
from dataclasses import dataclass, field
from importlib import resources
from typing import Any

import numpy as np

from davinci_sim.model.cameras import CameraConfig
from davinci_sim.sim.runtime.service import AsyncService
from davinci_sim.web.endoscope_stream import PoseStream
from davinci_sim.web.hosts import shown_host
from davinci_sim.web.protocol import OPERATOR_OPS, Command, ProtocolError, parse_message
from davinci_sim.web.vendor import three_dir, vendor_file
from davinci_sim.web.view import console_view, problems

_log = logging.getLogger("davinci_sim.web")

#: Binary frame message header: frame number (uint32), sim time (float64, s), length of the
#: left JPEG (uint32); then the left and the right JPEG.
FRAME_HEADER = struct.Struct("<IdI")

_CONTENT_TYPES = {
    ".html": "text/html; charset=utf-8",
    ".js": "text/javascript; charset=utf-8",
    ".css": "text/css; charset=utf-8",
    ".svg": "image/svg+xml",
    ".png": "image/png",
    ".csv": "text/csv; charset=utf-8",
    ".md": "text/markdown; charset=utf-8",
}


@dataclass(frozen=True)
class WebOptions:
    """How the web console serves."""

    host: str = "127.0.0.1"
    port: int = 8080
    """TCP port of the page (0: any free port)."""
    token: str | None = None
    """Required in the page's ``hello`` when set; required when ``host`` is not loopback."""
    state_rate: float = 30.0
    """Page state messages per second."""
    frame_rate: float = 30.0
    """Endoscope frames per second sent (the renderer's rate caps it)."""
    pose_rate: float = 60.0
    """Pose messages per second at most, for pages that draw the endoscope themselves."""
    jpeg_quality: int = 80
    hand_speed: float = 0.05
    """Hand speed at full input (an axis at ±1), m/s in HRSV."""
    turn_speed: float = 0.6
    """The wrist's angular speed at full input (a turn axis at ±1), rad/s in HRSV."""
    bedside_port: int | None = None
    """Port of the 3-D bedside view (viser) the page embeds; None: no 3-D view."""

    def __post_init__(self) -> None:
        for name in ("state_rate", "frame_rate", "pose_rate", "hand_speed", "turn_speed"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be > 0, got {v!r}")
        if not (0 <= self.port <= 65535):
            raise ValueError(f"port must be in 0..65535, got {self.port}")
        if not (1 <= self.jpeg_quality <= 100):
            raise ValueError(f"jpeg_quality must be in 1..100, got {self.jpeg_quality}")
        if self.token is not None and not self.token:
            raise ValueError("token must be a non-empty string or None")
        if not is_loopback(self.host) and self.token is None:
            raise ValueError(
                f"serving the web console on {self.host} (not loopback) needs a token "
                "(--token or $DAVINCI_SIM_TOKEN), the same as the rosbridge server's"
            )


def is_loopback(host: str) -> bool:
    if host in ("localhost", ""):
        return host == "localhost"
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


@dataclass(eq=False)
class _Client:
    """One connected page."""

    id: int
    ws: Any
    authed: bool
    latest: dict[str, Any] = field(default_factory=dict)
    """Kind -> the newest message not yet sent (state, frame): a slow page skips, never
    queues."""
    queue: list = field(default_factory=list)
    """Messages that must all arrive (errors, rows, control), in order."""
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    sent_frames: int = 0
    skipped_frames: int = 0
    stereo: bool = False
    """The page shows both eyes (it asked with the ``view`` op)."""
    source: str = "server"
    """Who draws the page's endoscope: ``server`` (JPEG frames) or ``page`` (poses)."""
    scene_sent: bool = False
    """The page that draws the endoscope has had the scene."""


class WebConsole(AsyncService):
    """The web console of a running system; see the module docstring.

    Args:
        handle: the running simulation (``System.handle``).
        options: where and how to serve.
        frames: the endoscope's frames (``System.frames()``: ``latest()`` returns a
            :class:`~davinci_sim.sim.runtime.render.StereoFrame` or None); None: no images.
        task: the task at the console (its conditions and metrics for the page), or None.
        camera: the endoscope's camera (image size, field of view, baseline).
        hand_mtms: MTMs whose hand the page steers (``<MTM>/hand`` components).
        study_task: the task (name or file) the study tab runs studies of; None: no study tab.
        model: the system's model (``System.model_source``: a callable returning the compiled
            model the server renders, the task's drawing included) for pages that draw the
            endoscope themselves; None: only the server's images.
        study_root: the folder the study tab's studies keep their folders in (rows as they
            finish, resumable with ``davinci-sim study --resume``); None: temporary folders.
        exercises: the exercises a page may switch to (``exercise`` op), with
        on_exercise: ``on_exercise(name) -> None or why not``, called to switch (``serve``
            restarts its system with that task); None: no switching.
        records: the trainee records' ``serve`` part
            (:class:`~davinci_sim.records.console.RecordsPart`): the page's trainee field
            sets whose attempts are recorded; None: the name only tags the rows.
    """

    def __init__(
        self,
        handle,
        options: WebOptions | None = None,
        *,
        frames=None,
        task=None,
        camera: CameraConfig | None = None,
        hand_mtms: tuple[str, ...] = (),
        study_task: str | None = None,
        records=None,
        model=None,
        study_root=None,
        exercises: tuple[str, ...] = (),
        on_exercise=None,
    ) -> None:
        from davinci_sim.web.study_job import StudyJob

        super().__init__()
        self.handle = handle
        self.study = (None if study_task is None
                      else StudyJob(study_task, self._notify, root=study_root))  # fmt: skip
        self.options = options or WebOptions()
        self.frames = frames
        self.task = task
        self.camera = camera or CameraConfig()
        self.hand_mtms = tuple(hand_mtms)
        self.rows: list[dict] = []
        """Finished repetitions, each tagged with the trainee's name (``trainee``)."""
        self.records = records
        """The trainee records (``set_trainee(name) -> name``; None: not recorded)."""
        self.trainee = "" if records is None else records.trainee
        self.operator: int | None = None
        self._wrist_free: set[str] = set()
        """MTMs whose teleoperations the page unlocked the rotation of (the wrist keys)."""
        self._messages: dict[str, tuple[str, str, float, int]] = {}
        """Each arm's and teleoperation's last error or warning: (level, text, sim time s,
        how many in a row); a teleoperation's warning is dropped when its state changes."""
        self._forwarded: dict[tuple[str, str], float] = {}
        """When (monotonic s) each (source, text) error was last sent to the pages."""
        self._clients: dict[int, _Client] = {}
        self._ids = itertools.count(1)
        self._port: int | None = None
        self._completed = 0
        self._state_tick: int | None = None  # (the tick of the last state sent to the pages)
        self._stats = {"frames_encoded": 0, "encode_time": 0.0, "states": 0, "poses": 0,
                       "pose_time": 0.0}  # fmt: skip
        self._model_source = model
        self.exercises = tuple(exercises) if on_exercise is not None else ()
        self._on_exercise = on_exercise
        self.poses: PoseStream | None = None
        """The :class:`~davinci_sim.web.endoscope_stream.PoseStream` (None: not offered)."""
        self._scene_text: str | None = None
        self._scene_error: str | None = None

    # ------------------------------------------------------------ lifecycle
    thread_name = "web-console"

    def start(self, timeout: float = 10.0) -> WebConsole:
        """Bind and serve; returns when pages can connect.

        Raises:
            OSError: if the port cannot be bound (e.g. taken).
        """
        return super().start(timeout)

    def stop(self, timeout: float = 10.0) -> None:
        """Close every page's connection, free the port, drop the study's files."""
        super().stop(timeout)
        if self.study is not None:
            self.study.close()

    def _notify(self, message: dict) -> None:
        """From another thread (the study's): send ``message`` to every page."""
        loop = self.loop
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(self._broadcast, message)

    @property
    def port(self) -> int:
        if self._port is None:
            raise RuntimeError("the web console is not started")
        return self._port

    @property
    def url(self) -> str:
        return f"http://{shown_host(self.options.host)}:{self.port}/"

    def statistics(self) -> dict:
        """Pages connected, frames encoded and mean encode time (s), state messages sent, and
        per page the frames sent and the frames it skipped (it was still sending one)."""
        s = dict(self._stats)
        s["pages"] = len(self._clients)
        s["frames_sent_skipped"] = [(c.sent_frames, c.skipped_frames)
                                    for c in self._clients.values()]  # fmt: skip
        n = s["frames_encoded"]
        s["encode_mean"] = s["encode_time"] / n if n else math.nan
        return s

    def results_csv(self) -> str:
        """The finished repetitions as CSV text (header first; empty without rows)."""
        if not self.rows:
            return ""
        columns = list(dict.fromkeys(k for row in self.rows for k in row))
        out = io.StringIO()
        writer = csv.DictWriter(out, fieldnames=columns)
        writer.writeheader()
        writer.writerows(self.rows)
        return out.getvalue()

    # ------------------------------------------------------------ the thread
    async def main(self) -> None:
        from websockets.asyncio.server import serve

        async with serve(
            self._handler,
            self.options.host,
            self.options.port,
            process_request=self._process_request,
            compression=None,
            max_size=64 * 1024,
            ping_interval=20,
            close_timeout=2,
            # (an HTTP answer drawn in a thread, the learning curves, can take longer than
            # websockets' default 10 s on a loaded machine: the page then got no answer)
            open_timeout=60,
        ) as server:
            self._port = server.sockets[0].getsockname()[1]
            tasks = [asyncio.create_task(self._state_loop())]
            if self.records is not None:  # (matplotlib's first figure: before a page asks)
                tasks.append(asyncio.create_task(asyncio.to_thread(self._warm_curve)))
            if self.frames is not None:
                tasks.append(asyncio.create_task(self._frame_loop()))
            if self._model_source is not None:
                tasks.append(asyncio.create_task(self._pose_loop()))
            loop = asyncio.get_running_loop()
            unsubscribe = self.handle.subscribe(
                lambda source, event, payload: self._on_sim_event(loop, source, event, payload)
            )
            self.ready()
            try:
                await self.stopping.wait()
            finally:
                unsubscribe()
                for t in tasks:
                    t.cancel()
                await asyncio.gather(*tasks, return_exceptions=True)
                await self._release_operator()
                server.close(close_connections=True)
                await server.wait_closed()

    # ------------------------------------------------------------ the simulation's messages
    #: The same error text from the same source reaches the pages at most this often, s.
    ERROR_REPEAT = 2.0

    def _on_sim_event(self, loop, source: str, event: str, payload) -> None:
        """From the simulation's thread: keep each source's last error or warning for the
        page's problems (:func:`~davinci_sim.web.view.problems`) and send errors to the
        pages, so a fault is shown with its reason."""
        if not hasattr(payload, "text"):
            return
        kept = self._messages.get(source)
        if event == "status":  # (a teleoperation's new state: its warning is over)
            if kept is not None and kept[0] == "warning":
                del self._messages[source]
            return
        if event not in ("error", "warning"):
            return
        repeats = kept[3] + 1 if kept is not None and kept[0] == event else 1
        self._messages[source] = (event, str(payload.text), float(payload.timestamp), repeats)
        if event == "error" and not loop.is_closed():
            loop.call_soon_threadsafe(self._forward_error, source, str(payload.text))

    def _forward_error(self, source: str, text: str) -> None:
        now = time.monotonic()
        if now - self._forwarded.get((source, text), -math.inf) < self.ERROR_REPEAT:
            return
        self._forwarded[(source, text)] = now
        self._broadcast({"op": "error", "message": text})

    async def _recover(self) -> None:
        """The remedy the page offers for its problems: every arm in FAULT is enabled and
        homed again (dvrk.md 2.4: FAULT accepts ``enable``), and the console's
        teleoperation, if on, is restarted, so each teleoperation sets its arms up and aligns
        its MTM again (SETTING_ARMS_STATE, dvrk.md 4.2)."""
        snap = self.handle.snapshot()
        for name, arm in snap.arms.items():
            if arm.operating_state.state == "FAULT":
                await self._call(name, "state_command", "enable")
                await self._call(name, "state_command", "home")
        self._messages.clear()
        console = (snap.extras or {}).get("console")
        if console is not None and console.teleop_enabled:
            await self._call("console", "teleop_enable", False)
            await self._call("console", "teleop_enable", True)

    # ------------------------------------------------------------ HTTP
    def _warm_curve(self) -> None:
        """Draw the learning curves once (imports matplotlib, caches the PNG)."""
        try:
            self.records.curve_png()
        except Exception:  # (the request itself says what is wrong)
            _log.debug("learning curves not drawn ahead", exc_info=True)

    async def _process_request(self, connection, request):
        path = request.path.split("?", 1)[0]
        if path == "/records/curve.png":  # drawn in a worker thread: the pages stream on
            return await self._curve(connection, request)
        return self._http(connection, request)

    async def _curve(self, connection, request):
        """The trainee's learning curves (PNG) from the trainee records; with a token, only
        for a request that carries it (``?token=``): the records are personal data."""
        import hmac
        from urllib.parse import parse_qs, urlsplit

        from websockets.datastructures import Headers
        from websockets.http11 import Response

        if self.records is None:
            return connection.respond(404, "no trainee records on this server\n")
        if self.options.token is not None:
            given = parse_qs(urlsplit(request.path).query).get("token", [""])[0]
            if not hmac.compare_digest(given.encode(), self.options.token.encode()):
                return connection.respond(403, "wrong or missing token\n")
        try:
            body = await asyncio.to_thread(self.records.curve_png)
        except Exception:  # (its text may name a path of the server: logged, not sent)
            _log.exception("cannot draw the learning curves")
            return connection.respond(500, "cannot draw the learning curves\n")
        headers = Headers([("Content-Type", "image/png"), ("Cache-Control", "no-store")])
        return Response(200, "OK", headers, body)

    def _http(self, connection, request):
        from websockets.datastructures import Headers
        from websockets.http11 import Response

        path = request.path.split("?", 1)[0]
        if path == "/ws":
            return None  # the websocket handshake goes on
        if path == "/results.csv":
            body = self.results_csv().encode("utf-8")
            headers = Headers(
                [
                    ("Content-Type", "text/csv; charset=utf-8"),
                    ("Content-Disposition", 'attachment; filename="results.csv"'),
                    ("Cache-Control", "no-store"),
                ]
            )
            return Response(200, "OK", headers, body)
        if path.startswith("/vendor/"):
            body = vendor_file(path[len("/vendor/") :])
            if body is None:
                return connection.respond(404, f"not found: {path}\n")
            kind = _CONTENT_TYPES.get(path[path.rfind(".") :], "text/plain; charset=utf-8")
            headers = Headers([("Content-Type", kind), ("Cache-Control", "max-age=86400")])
            return Response(200, "OK", headers, body)
        if path.startswith("/study/"):
            name = path[len("/study/") :]
            body = None if self.study is None else self.study.file(name)
            if body is None:
                return connection.respond(404, f"not found: {path}\n")
            kind = _CONTENT_TYPES.get(name[name.rfind(".") :], "application/octet-stream")
            headers = Headers([("Content-Type", kind), ("Cache-Control", "no-store")])
            return Response(200, "OK", headers, body)
        name = "index.html" if path in ("/", "/index.html") else path.lstrip("/")
        body = _static(name)
        if body is None:
            return connection.respond(404, f"not found: {path}\n")
        suffix = name[name.rfind(".") :]
        headers = Headers(
            [
                ("Content-Type", _CONTENT_TYPES.get(suffix, "application/octet-stream")),
                ("Cache-Control", "no-cache"),
            ]
        )
        return Response(200, "OK", headers, body)

    # ------------------------------------------------------------ a page
    async def _handler(self, ws) -> None:
        client = _Client(next(self._ids), ws, authed=self.options.token is None)
        self._clients[client.id] = client
        writer = asyncio.create_task(self._writer(client))
        try:
            self._push(client, self._hello(client))
            async for message in ws:
                await self._on_message(client, message)
        except Exception as e:  # a broken connection ends this page only
            if not _closed(e):
                _log.exception("page %d: %s", client.id, e)
        finally:
            self._clients.pop(client.id, None)
            writer.cancel()
            await asyncio.gather(writer, return_exceptions=True)
            if self.operator == client.id:
                await self._release_operator()
                self._broadcast_control()

    def _hello(self, client: _Client) -> dict:
        """What a page is told first: before it proved the token, only that it must."""
        if not client.authed:
            return {"op": "hello", "client": client.id, "needs_token": True}
        info: dict[str, Any] = {
            "op": "hello",
            "client": client.id,
            "needs_token": not client.authed,
            "camera": {"width": self.camera.width, "height": self.camera.height},
            "hands": list(self.hand_mtms),
            "hand_speed": self.options.hand_speed,
            "turn_speed": self.options.turn_speed,
            "bedside_port": self.options.bedside_port,
            "operator": self.operator,
            "trainee": self.trainee,
            "study": self.study is not None,
            "records": self.records is not None,
            "page_view": self._model_source is not None and three_dir() is not None,
            "exercises": list(self.exercises),
            # (a stepped simulation ticks only what pages ask for: the op "advance")
            "stepped": getattr(self.handle, "stepped", False) is True,
        }
        task = self.task
        if task is not None:
            info["task"] = {
                "name": task.name,
                "kind": task.kind,
                "description": getattr(task, "description", ""),
                "psm": task.teleop.psm,
                "mtm": task.teleop.mtm,
                "conditions": [dict(c) for c in task.conditions],
                "fixture": dict(task.fixture_spec),
                "fixture_types": sorted(task.FIXTURE_TYPES),
                "metrics": [
                    {
                        "name": m.name,
                        "unit": m.unit,
                        "better": m.better,
                        "label": m.label,
                        "display": None if m.display is None else list(m.display),
                    }
                    for m in task.METRICS  # fmt: skip
                ],
            }
        return info

    def _push(self, client: _Client, message: dict) -> None:
        client.queue.append(_dumps(message))
        client.wake.set()

    def _broadcast(self, message: dict, *, latest: str | None = None) -> None:
        text = _dumps(message)
        for client in list(self._clients.values()):
            if not client.authed:
                continue
            if latest is None:
                client.queue.append(text)
            else:
                client.latest[latest] = text
            client.wake.set()

    async def _writer(self, client: _Client) -> None:
        ws = client.ws
        while True:
            await client.wake.wait()
            client.wake.clear()
            while client.queue:
                await ws.send(client.queue.pop(0))
            for kind in ("state", "frame", "poses"):
                message = client.latest.pop(kind, None)
                if message is not None:
                    await ws.send(message)
                    if kind == "frame":
                        client.sent_frames += 1

    # ------------------------------------------------------------ commands
    async def _on_message(self, client: _Client, message) -> None:
        try:
            command = parse_message(message)
        except ProtocolError as e:
            self._push(client, {"op": "error", "message": str(e)})
            return
        if command.op == "hello":
            if not client.authed:
                if command.args.get("token") != self.options.token:
                    self._push(client, {"op": "error", "message": "wrong or missing token"})
                    return
                client.authed = True
                self._push(client, self._hello(client))  # now the whole description
            self._push(client, {"op": "welcome", "client": client.id, "operator": self.operator})
            return
        if not client.authed:
            self._push(client, {"op": "error", "message": "send hello with the token first"})
            return
        if command.op == "view":
            client.stereo = command.args["stereo"]
            source = command.args.get("source", "server")
            why = self._no_page_view()
            if source == "page" and why is not None:
                self._push(client, {"op": "error", "message": f"view: {why}"})
                source = "server"
            if source == "page" and client.source != "page":
                client.scene_sent = False
            client.source = source
            self._send_scene()
            return
        if command.op == "ping":
            self._push(client, {"op": "pong", "t": command.args["t"], "server": time.time()})
            return
        if command.op == "trainee":
            name = command.args["name"]
            if self.records is not None:  # the next attempts are recorded as this trainee's
                try:
                    name = self.records.set_trainee(name)
                except ValueError as e:
                    self._push(client, {"op": "error", "message": f"trainee: {e}"})
                    return
            self.trainee = name
            self._broadcast({"op": "trainee", "name": self.trainee})
            return
        if command.op == "control":
            await self._control(client, command.args["take"])
            return
        if command.op == "advance":  # (any page: a script waits before it takes control)
            await self._advance(client, command.args["seconds"])
            return
        if command.op in OPERATOR_OPS and self.operator != client.id:
            who = "nobody" if self.operator is None else f"page {self.operator}"
            self._push(
                client,
                {"op": "error", "message": f"{command.op}: {who} operates; take control first"},
            )
            return
        try:
            await self._dispatch(command)
        except CommandRefused as e:
            self._push(client, {"op": "error", "message": str(e)})

    async def _call(self, target: str, method: str, *args, timeout: float = 5.0, **kwargs):
        try:
            future = self.handle.call(target, method, *args, **kwargs)
            result = await asyncio.wait_for(asyncio.wrap_future(future), timeout)
        except (KeyError, AttributeError, TypeError, ValueError, RuntimeError) as e:
            raise CommandRefused(f"{target}.{method}: {e}") from None
        except TimeoutError:
            raise CommandRefused(f"{target}.{method}: no answer in {timeout:g} s") from None
        accepted = getattr(result, "accepted", True)
        if not accepted:
            raise CommandRefused(getattr(result, "message", f"{target}.{method} refused"))
        return result

    async def _dispatch(self, command: Command) -> None:
        a = command.args
        op = command.op
        if op == "input":
            mtm = a["mtm"]
            if mtm not in self.hand_mtms:
                raise CommandRefused(f"input: no hand on {mtm}; hands: {list(self.hand_mtms)}")
            synthetic = (self.handle.snapshot().extras or {}).get("synthetic")
            if synthetic is not None and synthetic["running"] and any(a["axes"]):
                raise CommandRefused("input: a synthetic trainee has the MTM; stop it first")
            axes = np.asarray(a["axes"], dtype=float)
            # Screen right/up/in -> HRSV: x is the image's left, y up, z into the scene.
            v = self.options.hand_speed * np.array([-axes[0], axes[1], axes[2]])
            speed = float(np.linalg.norm(v))
            if speed > self.options.hand_speed:  # diagonal input: the speed stays the max
                v *= self.options.hand_speed / speed
            w = None
            if "turn" in a:  # the same screen -> HRSV map, for rates about those axes
                turn = np.asarray(a["turn"], dtype=float)
                w = self.options.turn_speed * np.array([-turn[0], turn[1], turn[2]])
                rate = float(np.linalg.norm(w))
                if rate > self.options.turn_speed:
                    w *= self.options.turn_speed / rate
                w = w.tolist()
                if any(w) and mtm not in self._wrist_free:
                    await self._free_wrist(mtm)
                    w = None
            if mtm in self._wrist_free:  # the wrist turns only while the tool follows
                extras = self.handle.snapshot().extras or {}
                following = any(extras[n].following for n in self._teleops_of(mtm))
                if not following:
                    w = None
                    if (extras.get(f"{mtm}/hand") or {}).get("wrist_held"):
                        await self._call(f"{mtm}/hand", "relax_wrist")
            await self._call(f"{mtm}/hand", "command", v.tolist(), a.get("gripper"), w)
        elif op == "button":
            await self._call("console", "press" if a["pressed"] else "release", a["name"])
        elif op == "condition":
            await self._call("task", "set_condition", a["condition"])
        elif op == "task":
            await self._call("task", "reset")
        elif op == "exercise":
            name = a["task"]
            if name not in self.exercises or self._on_exercise is None:
                offered = ", ".join(self.exercises) or "none on this server"
                raise CommandRefused(f"exercise: {name!r} is not offered ({offered})")
            why = self._on_exercise(name)
            if why is not None:
                raise CommandRefused(f"exercise: {why}")
            self._broadcast({"op": "exercise", "task": name})
        elif op == "teleop":
            if "enable" in a:
                await self._call("console", "teleop_enable", a["enable"])
            if "scale" in a:
                await self._call("console", "set_scale", a["scale"])
        elif op == "recover":
            await self._recover()
        elif op == "arms":
            for name in self.handle.snapshot().arms:
                await self._call(name, "state_command", a["action"])
        elif op == "study":
            if self.study is None:
                raise CommandRefused("study: this console has no study (no path task)")
            why = self.study.start(a["subjects"], a["repetitions"])
            if why is not None:
                raise CommandRefused(f"study: {why}")
        elif op == "synthetic":
            if a["action"] == "start":
                kwargs = {k: a[k] for k in ("subject", "practice") if k in a}
                for mtm in self.hand_mtms:
                    await self._call(f"{mtm}/hand", "release")
                await self._call("synthetic", "start", **kwargs)
            else:
                await self._call("synthetic", "stop")
                await self._grasp()

    async def _free_wrist(self, mtm: str) -> None:
        """The first turn of ``mtm``'s wrist keys: its teleoperations' rotation, locked for a
        rate input (``system.build``: a relaxed wrist must not drift the tool), is unlocked,
        so the tool turns with the hand, which from then on holds its wrist
        (:class:`~davinci_sim.devices.hand_input.HandInput`). The teleoperation re-aligns
        first, as the dVRK's does on unlocking (dvrk.md 4.2); releasing control locks it
        again."""
        for name in self._teleops_of(mtm):
            await self._call(name, "lock_rotation", False)
        self._wrist_free.add(mtm)

    def _teleops_of(self, mtm: str) -> list[str]:
        extras = self.handle.snapshot().extras or {}
        return [n for n, s in extras.items()
                if hasattr(s, "following") and getattr(s, "mtm", None) == mtm]  # fmt: skip

    async def _grasp(self) -> None:
        for mtm in self.hand_mtms:
            await self._call(f"{mtm}/hand", "grasp")

    async def _control(self, client: _Client, take: bool) -> None:
        if take:
            if self.operator not in (None, client.id):
                self._push(
                    client,
                    {
                        "op": "error",
                        "message": f"page {self.operator} operates now; "
                        "they must release control first",
                    },
                )
                return
            if self.operator is None:
                self.operator = client.id
                try:
                    # Taking control is a person sitting at the console: head in, hands on
                    # both handles. A handle nobody holds floats in gravity compensation, and
                    # the guidance force on the following tool is not a damper on the
                    # handle's own motion: through the teleoperation's lag it pumps an
                    # unheld MTM into a growing oscillation that faults the PSM within
                    # seconds. The hand holds the handle where it is until a key moves it.
                    await self._grasp()
                    await self._call("console", "press", "operator_present")
                    await self._call("console", "teleop_enable", True)
                except CommandRefused as e:
                    self._push(client, {"op": "error", "message": str(e)})
        elif self.operator == client.id:
            await self._release_operator()
        self._broadcast_control()

    def _broadcast_control(self) -> None:
        self._broadcast({"op": "control", "operator": self.operator})

    async def _release_operator(self) -> None:
        """The operator leaves: the hands let go and the head sensor is released."""
        if self.operator is None:
            return
        self.operator = None
        relock = [(n, "lock_rotation", (True,)) for m in sorted(self._wrist_free)
                  for n in self._teleops_of(m)]  # fmt: skip
        self._wrist_free.clear()
        for target, method, args in [
            *((f"{m}/hand", "release", ()) for m in self.hand_mtms),
            *relock,
            ("console", "release", ("operator_present",)),
        ]:
            try:
                await self._call(target, method, *args)
            except CommandRefused as e:
                _log.warning("releasing the console: %s", e)

    # ------------------------------------------------------------ streams
    def _snapshot(self):
        """The simulation's latest snapshot, or None (not started yet, or stopping)."""
        try:
            return self.handle.snapshot()
        except Exception as e:
            _log.debug("no snapshot: %s", e)
            return None

    async def _state_loop(self) -> None:
        period = 1.0 / self.options.state_rate
        while True:
            await asyncio.sleep(period)
            if not self._clients:
                continue
            snap = self._snapshot()
            if snap is None:
                continue
            self._collect_rows(snap)
            if snap.tick == self._state_tick:  # (sent already, by this loop or an advance)
                continue
            view = self._state_message(snap)
            if view is not None:
                self._broadcast(view, latest="state")

    def _state_message(self, snap) -> dict | None:
        """The page's ``state`` message of ``snap`` (None if the view cannot be made), its
        tick noted as sent."""
        self._state_tick = snap.tick
        try:
            view = console_view(snap, self.camera, self.task)
        except Exception:  # a bug in the view must not end the stream
            _log.exception("cannot make the page's state")
            return None
        view["problems"] = problems(view, dict(self._messages))
        view["op"] = "state"
        view["operator"] = self.operator
        view["pages"] = len(self._clients)
        self._stats["states"] += 1
        return view

    async def _advance(self, client: _Client, seconds: float) -> None:
        """A stepped server (``ServeOptions.stepped``): tick ``seconds`` of simulated time
        more, then send ``client`` the state there and ``advanced`` (in that order; the
        other pages get the state as usual). Refused with ``advanced``'s ``refused`` when
        the simulation keeps time by itself."""
        if getattr(self.handle, "stepped", False) is not True:
            why = ("advance: this console's simulation keeps time by itself (only a server "
                   "started stepped, for scripted pages, ticks on request)")  # fmt: skip
            self._push(client, {"op": "advanced", "refused": why})
            return
        try:
            tick = await asyncio.wrap_future(self.handle.advance(seconds))
        except Exception as e:  # (a loop that stopped: the page is told, the server goes on)
            self._push(client, {"op": "advanced", "refused": f"advance: {e}"})
            return
        snap = self._snapshot()
        view = None if snap is None else self._state_message(snap)
        if view is not None:
            self._collect_rows(snap)
            self._broadcast(view, latest="state")
            mine = client.latest.pop("state", None)
            if mine is not None:  # (this page's state goes before its answer, never after)
                client.queue.append(mine)
        self._push(client, {"op": "advanced", "tick": int(tick)})

    def _collect_rows(self, snap) -> None:
        task = (snap.extras or {}).get("task")
        if task is None or task.completed <= self._completed:
            return
        self._completed = task.completed
        row = {"trainee": self.trainee, **task.last}
        self.rows.append(row)
        self._broadcast({"op": "row", "row": row})

    async def _frame_loop(self) -> None:
        period = 1.0 / self.options.frame_rate
        loop = asyncio.get_running_loop()
        last = None
        while True:
            t0 = loop.time()
            frame = None
            if any(c.authed and c.source == "server" for c in self._clients.values()):
                try:
                    frame = self.frames.latest()
                except Exception:
                    _log.exception("no endoscope frame")
            if frame is not None and frame.frame != last:
                last = frame.frame
                start = time.perf_counter()
                stereo = any(c.stereo for c in self._clients.values())
                message = await loop.run_in_executor(None, self._encode, frame, stereo)
                self._stats["encode_time"] += time.perf_counter() - start
                self._stats["frames_encoded"] += 1
                for client in list(self._clients.values()):
                    if client.authed and client.source == "server":
                        if "frame" in client.latest:
                            client.skipped_frames += 1
                        client.latest["frame"] = message
                        client.wake.set()
            await asyncio.sleep(max(0.0, period - (loop.time() - t0)))

    def _no_page_view(self) -> str | None:
        """Why a page cannot draw the endoscope itself here (None: it can)."""
        if self._model_source is None:
            return "this server has no model for the page"
        return self._scene_error

    def _send_scene(self) -> None:
        """The scene to every page that draws the endoscope and has not had it (a page that
        asked before the model was built gets it when it is)."""
        if self._scene_text is None:
            return
        for client in self._clients.values():
            if client.authed and client.source == "page" and not client.scene_sent:
                client.queue.append(self._scene_text)
                client.scene_sent = True
                client.wake.set()

    async def _pose_loop(self) -> None:
        """The pose messages of pages that draw the endoscope: the model is built first (in
        a worker thread: a second or so), then each new snapshot's ``qpos`` goes out."""
        try:
            poses = await asyncio.to_thread(lambda: PoseStream(_compiled(self._model_source)))
            scene = poses.scene(self.camera.baseline_m)
            self.poses = poses
            self._scene_text = _dumps(scene)
        except Exception as e:
            _log.exception("the page cannot draw the endoscope: no scene")
            self._scene_error = f"the page's scene could not be built ({type(e).__name__})"
            for client in self._clients.values():
                if client.source == "page":
                    client.source = "server"
                    self._push(client, {"op": "error", "message": f"view: {self._scene_error}"})
            return
        self._send_scene()
        period = 1.0 / self.options.pose_rate
        last_tick = None
        latest = getattr(self.handle, "latest_qpos", None)  # (the loop's every tick)
        while True:
            await asyncio.sleep(period)
            clients = [c for c in self._clients.values() if c.authed and c.source == "page"]
            if not clients:
                continue
            joints = self._latest_joints(latest)
            if joints is None or joints[0] == last_tick:
                continue
            tick, t, qpos = joints
            last_tick = tick
            start = time.perf_counter()
            try:
                message = poses.message(qpos, tick, t)
            except ValueError:
                _log.exception("no pose message")
                continue
            self._stats["pose_time"] += time.perf_counter() - start
            self._stats["poses"] += 1
            for client in clients:
                client.latest["poses"] = message
                client.wake.set()

    def _latest_joints(self, latest) -> tuple[int, float, np.ndarray] | None:
        """The joints to draw: ``(tick, time s, qpos)`` the loop wrote last (``latest``: a
        process runner's every tick, up to a snapshot period fresher), else the latest
        snapshot's (``extras["qpos"]``); None where there are none."""
        if latest is not None:
            try:
                joints = latest()
            except Exception as e:  # (the loop stopping)
                _log.debug("no joints: %s", e)
                joints = None
            if joints is not None:
                return joints
        snap = self._snapshot()
        qpos = None if snap is None else (snap.extras or {}).get("qpos")
        return None if qpos is None else (snap.tick, snap.time, qpos)

    def _encode(self, frame, stereo: bool = True) -> bytes:
        from PIL import Image

        parts = [b"", b""]
        for k, image in enumerate((frame.left, frame.right) if stereo else (frame.left,)):
            out = io.BytesIO()
            Image.fromarray(image).save(out, format="JPEG", quality=self.options.jpeg_quality)
            parts[k] = out.getvalue()
        # (frame numbers take 31 bits: a first field of all ones is a pose message's)
        header = FRAME_HEADER.pack(frame.frame & 0x7FFFFFFF, frame.time, len(parts[0]))
        return header + parts[0] + parts[1]


class CommandRefused(Exception):
    """A command the simulation (or the console's rules) refused; shown in the page."""


def _compiled(model_source):
    """The compiled model of ``model_source`` (a model, or a callable returning one)."""
    return model_source() if callable(model_source) else model_source


def _static(name: str) -> bytes | None:
    if "/" in name or "\\" in name or name.startswith("."):
        return None  # only the files of web/static, no paths
    try:
        return resources.files("davinci_sim.web").joinpath("static", name).read_bytes()
    except (FileNotFoundError, IsADirectoryError, NotADirectoryError):
        return None


def _dumps(message: dict) -> str:
    """JSON for the page: numpy values as numbers, non-finite floats as null (JSON has no
    NaN; the page shows "–")."""
    try:
        return json.dumps(message, allow_nan=False, default=_json_default)
    except ValueError:
        return json.dumps(_finite_only(message), allow_nan=False, default=_json_default)


def _finite_only(o):
    if isinstance(o, dict):
        return {k: _finite_only(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_finite_only(v) for v in o]
    if isinstance(o, np.ndarray):
        return _finite_only(o.tolist())
    if isinstance(o, (float, np.floating)) and not math.isfinite(o):
        return None
    return o


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer, np.bool_)):
        return o.item()
    raise TypeError(f"not JSON: {type(o).__name__}")


def _closed(e: BaseException) -> bool:
    from websockets.exceptions import ConnectionClosed

    return isinstance(e, (ConnectionClosed, asyncio.CancelledError))
