"""A class on one server (``davinci-sim class``): a system per trainee and a lobby page.

Each trainee gets a ``davinci-sim serve`` process of their own (:func:`serve_command`): their
own system with its 1 kHz loop in its own process, their own web console on a port of their
own (the lobby's port + 1 + k), their attempts recorded under their name. The trainees'
browsers draw the endoscope themselves (the page's three.js view), so the server's work per
trainee is the loop, the state and pose messages. A system that stops or fails touches no
other. The lobby (:class:`Classroom`, its own HTTP server on the lobby's port) lists the
trainees with a link to each console and how their system is doing (starting, ready, the
last warning it printed, exited); ``/status.json`` gives the same as JSON.

With ``ray_address`` the systems are Ray actors spread over a Ray cluster's nodes instead
(:mod:`~davinci_sim.web.class_ray`); the lobby stays here and links to each node.

Served beyond loopback, every console and the lobby need the token (``$DAVINCI_SIM_TOKEN``,
passed to the children in their environment, never on a command line that ``ps`` shows).
"""

from __future__ import annotations

import html
import json
import logging
import os
import re
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import TYPE_CHECKING
from urllib.parse import parse_qs, urlsplit

from davinci_sim.web.hosts import shown_host

if TYPE_CHECKING:
    from davinci_sim.web.class_ray import RaySystems

_log = logging.getLogger("davinci_sim.web")

#: The first line a serve prints when its console is up: ``web console: <url>``.
_READY = re.compile(r"web console: (\S+)")
#: Lines of a serve's output the lobby shows (warnings, the loop's figures at the end).
_NOTABLE = re.compile(r"real time|loop: |FAULT|error|Error")


@dataclass(frozen=True)
class ClassOptions:
    """What ``davinci-sim class`` serves."""

    trainees: tuple[str, ...]
    """The trainees' names, one system each."""
    task: str = "seed_path"
    host: str = "127.0.0.1"
    port: int = 8080
    """The lobby's port; trainee k's console is on ``port + 1 + k``."""
    token: str | None = None
    realtime_priority: int | None = None
    """SCHED_FIFO priority of every loop process (``serve --realtime-priority``)."""
    records: str | None = None
    """The trainee records file all systems record in (None: the default)."""
    extra: tuple[str, ...] = field(default_factory=tuple)
    """More ``serve`` arguments for every system (e.g. ``--fast``)."""
    ray_address: str | None = None
    """Run the systems as Ray actors on the Ray cluster at this address (``"auto"``: the
    one this machine belongs to), spread over its nodes (:mod:`~davinci_sim.web.class_ray`);
    None: processes of this machine."""
    cpus_per_trainee: float = 1.0
    """CPUs Ray reserves for each system (its loop takes about one core)."""

    def __post_init__(self) -> None:
        names = list(self.trainees)
        if not names:
            raise ValueError("a class needs at least one trainee")
        if len(set(names)) != len(names):
            raise ValueError(f"trainee names must differ, got {names}")
        for name in names:
            if not name.strip() or len(name) > 64:
                raise ValueError(f"bad trainee name {name!r} (1-64 characters)")
        if not self.cpus_per_trainee > 0:
            raise ValueError(f"cpus_per_trainee must be > 0, got {self.cpus_per_trainee}")
        if not 0 <= self.port or self.port + len(names) > 65535:
            raise ValueError(f"ports {self.port}..{self.port + len(names)} are not all valid")


def serve_command(options: ClassOptions, k: int) -> list[str]:
    """The command line of trainee ``k``'s system (the token goes in the environment)."""
    command = [sys.executable, "-c", "from davinci_sim.cli import main; raise SystemExit(main())",
               "serve", "--task", options.task, "--home", "--trainee", options.trainees[k],
               "--no-server", "--no-bedside", "--host", options.host,
               "--web-port", str(options.port + 1 + k)]  # fmt: skip
    if options.realtime_priority is not None:
        command += ["--realtime-priority", str(options.realtime_priority)]
    if options.records is not None:
        command += ["--records", options.records]
    return command + list(options.extra)


@dataclass
class TraineeSystem:
    """One trainee's running system (a ``serve`` process of this machine)."""

    name: str
    port: int
    process: subprocess.Popen
    url: str | None = None
    """The console's URL once it is up."""
    notes: list[str] = field(default_factory=list)
    """The last notable lines it printed (warnings, the loop's figures)."""
    node: str | None = None
    """Where it runs (a Ray node's id; None: this machine)."""

    @property
    def state(self) -> str:
        code = self.process.poll()
        if code is not None:
            return f"exited ({code})"
        return "ready" if self.url else "starting"

    def status(self) -> dict:
        """What the lobby shows of it (JSON-ready)."""
        return {"name": self.name, "port": self.port, "url": self.url, "state": self.state,
                "notes": self.notes[-5:], "node": self.node}  # fmt: skip


def class_environment(options: ClassOptions) -> dict[str, str]:
    """The systems' environment: this process's, with the class's token."""
    env = dict(os.environ)
    if options.token is not None:
        env["DAVINCI_SIM_TOKEN"] = options.token
    return env


def start_system(options: ClassOptions, k: int, env: dict[str, str], *,
                 shown_host: str | None = None) -> TraineeSystem:  # fmt: skip
    """Start trainee ``k``'s ``serve`` process here, and a thread following its output (the
    console's URL, with ``shown_host`` as its host if given; notable lines)."""
    process = subprocess.Popen(
        serve_command(options, k), env=env, stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT, text=True, bufsize=1, start_new_session=True,
    )  # fmt: skip
    system = TraineeSystem(options.trainees[k], options.port + 1 + k, process)
    threading.Thread(target=_follow, args=(system, shown_host), daemon=True,
                     name=f"class-{system.name}").start()  # fmt: skip
    return system


def _follow(system: TraineeSystem, shown_host: str | None) -> None:
    assert system.process.stdout is not None
    for line in system.process.stdout:
        line = line.rstrip()
        found = _READY.search(line)
        if found and system.url is None:
            url = found.group(1)
            if shown_host is not None:
                parts = urlsplit(url)
                url = parts._replace(netloc=f"{shown_host}:{parts.port}").geturl()
            system.url = url
        elif _NOTABLE.search(line):
            system.notes.append(line)
            del system.notes[:-20]


def interrupt(systems: list[TraineeSystem]) -> None:
    """Ask every system to stop as Ctrl-C does (each prints its loop's figures)."""
    for s in systems:
        if s.process.poll() is None:
            try:
                os.killpg(s.process.pid, signal.SIGINT)
            except ProcessLookupError:
                pass


def wait_stopped(systems: list[TraineeSystem], timeout: float) -> None:
    """Wait for the interrupted systems; kill what is still running after ``timeout`` s."""
    end = time.monotonic() + timeout
    for s in systems:
        try:
            s.process.wait(max(0.1, end - time.monotonic()))
        except subprocess.TimeoutExpired:
            os.killpg(s.process.pid, signal.SIGKILL)
            s.process.wait()
    time.sleep(0.2)  # (their last lines reach the followers)


class LocalSystems:
    """The class's systems as processes of this machine."""

    def __init__(self, options: ClassOptions) -> None:
        self.options = options
        self.systems: list[TraineeSystem] = []

    def start(self) -> None:
        env = class_environment(self.options)
        for k in range(len(self.options.trainees)):
            self.systems.append(start_system(self.options, k, env))

    def status(self) -> list[dict]:
        return [s.status() for s in self.systems]

    def stop(self, timeout: float) -> None:
        interrupt(self.systems)
        wait_stopped(self.systems, timeout)

    def close(self) -> None:
        """Nothing left to release (the processes have ended)."""


class Classroom:
    """The systems of a class and their lobby; see the module docstring."""

    def __init__(self, options: ClassOptions) -> None:
        self.options = options
        if options.ray_address is None:
            self.systems: LocalSystems | RaySystems = LocalSystems(options)
        else:
            from davinci_sim.web.class_ray import RaySystems

            self.systems = RaySystems(options)
        self._lobby: ThreadingHTTPServer | None = None

    def start(self) -> Classroom:
        """Start every system (at once) and the lobby; returns when the lobby serves."""
        try:
            self.systems.start()
            self._lobby = ThreadingHTTPServer((self.options.host, self.options.port),
                                              _handler(self))  # fmt: skip
        except BaseException:
            self.stop()
            raise
        thread = threading.Thread(target=self._lobby.serve_forever, daemon=True, name="lobby")
        thread.start()
        return self

    @property
    def url(self) -> str:
        return f"http://{shown_host(self.options.host)}:{self.options.port}/"

    def wait_ready(self, timeout: float) -> bool:
        """Wait until every system's console is up (False: one exited or the time ran out)."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            status = self.status()
            if any(s["state"].startswith("exited") for s in status):
                return False
            if all(s["state"] == "ready" for s in status):
                return True
            time.sleep(0.2)
        return False

    def status(self) -> list[dict]:
        return self.systems.status()

    def stop(self, timeout: float = 30.0) -> list[dict]:
        """Stop every system as Ctrl-C does (each prints its loop's figures) and the lobby;
        returns the final :meth:`status`."""
        self.systems.stop(timeout)
        final = self.status()
        if self._lobby is not None:
            self._lobby.shutdown()
            self._lobby.server_close()
            self._lobby = None
        self.systems.close()
        return final


def _handler(room: Classroom):
    class Lobby(BaseHTTPRequestHandler):
        def do_GET(self) -> None:  # noqa: N802 (http.server's name)
            parts = urlsplit(self.path)
            token = room.options.token
            if token is not None and parse_qs(parts.query).get("token", [""])[0] != token:
                self._send(403, "text/plain; charset=utf-8", b"wrong or missing token\n")
                return
            if parts.path == "/status.json":
                body = json.dumps(room.status()).encode()
                self._send(200, "application/json", body)
            elif parts.path in ("/", "/index.html"):
                self._send(200, "text/html; charset=utf-8", _lobby_html(room).encode())
            else:
                self._send(404, "text/plain; charset=utf-8", b"not found\n")

        def _send(self, code: int, kind: str, body: bytes) -> None:
            self.send_response(code)
            self.send_header("Content-Type", kind)
            self.send_header("Cache-Control", "no-store")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, format, *args) -> None:  # (quiet: the class's output is its own)
            _log.debug("lobby: " + format, *args)

    return Lobby


def _lobby_html(room: Classroom) -> str:
    token = room.options.token
    rows = []
    for s in room.status():
        link = s["url"] and s["url"] + (f"?token={token}" if token else "")
        name = html.escape(s["name"])
        cell = f'<a href="{html.escape(link)}">{name}</a>' if link else name
        notes = "<br>".join(html.escape(n) for n in s["notes"]) or ""
        where = html.escape(s["node"][:8]) if s["node"] else "here"
        rows.append(f"<tr><td>{cell}</td><td>{html.escape(s['state'])}</td><td>{where}</td>"
                    f"<td>{s['port']}</td><td class=n>{notes}</td></tr>")  # fmt: skip
    return (
        "<!doctype html><html><head><meta charset=utf-8><meta http-equiv=refresh content=5>"
        "<title>davinci-sim class</title><style>body{font:14px system-ui;margin:2em;"
        "background:#111418;color:#ddd}a{color:#6cf}td,th{padding:4px 12px;text-align:left}"
        ".n{color:#999;font-size:12px}</style></head><body>"
        f"<h1>davinci-sim class: {html.escape(room.options.task)}</h1>"
        "<p>Each trainee opens their own console (the name is the link); every system "
        "has its own 1 kHz loop and records the attempts under the trainee's name.</p>"
        "<table><tr><th>trainee</th><th>system</th><th>node</th><th>port</th>"
        "<th>last notes</th></tr>" + "".join(rows) + "</table></body></html>"
    )
