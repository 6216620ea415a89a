"""Switching the exercise from the page: the console refuses what it does not offer, and
``serve`` restarts its system with the chosen exercise on the same port."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time

from websockets.sync.client import connect

from davinci_sim.web.server import WebConsole, WebOptions


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class _Handle:
    """Just enough of a SimHandle for the console's hello and commands (no simulation)."""

    def subscribe(self, callback):
        return lambda: None

    def snapshot(self):
        raise RuntimeError("no simulation here")


def messages_until(ws, op: str, timeout: float = 20.0) -> dict:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        m = ws.recv(timeout=max(0.01, end - time.monotonic()))
        if isinstance(m, str) and json.loads(m).get("op") == op:
            return json.loads(m)
    raise AssertionError(f"no {op!r} message")


def test_the_console_switches_only_to_an_offered_exercise_and_only_for_its_operator():
    asked: list[str] = []
    web = WebConsole(_Handle(), WebOptions(port=0), exercises=("seed_path", "ring_walk"),
                     on_exercise=lambda name: asked.append(name) or None).start()  # fmt: skip
    try:
        url = f"ws://127.0.0.1:{web.port}/ws"
        with connect(url) as operator, connect(url) as other:
            hello = json.loads(operator.recv(timeout=10))
            assert hello["exercises"] == ["seed_path", "ring_walk"]
            json.loads(other.recv(timeout=10))
            for ws in (operator, other):
                ws.send(json.dumps({"op": "hello"}))
            operator.send(json.dumps({"op": "control", "take": True}))
            messages_until(operator, "control")
            other.send(json.dumps({"op": "exercise", "task": "ring_walk"}))
            assert "take control first" in messages_until(other, "error")["message"]
            operator.send(json.dumps({"op": "exercise", "task": "peg_transfer"}))
            assert "not offered" in messages_until(operator, "error")["message"]
            assert asked == []
            operator.send(json.dumps({"op": "exercise", "task": "ring_walk"}))
            assert messages_until(other, "exercise")["task"] == "ring_walk"  # every page told
            assert asked == ["ring_walk"]
    finally:
        web.stop()


def test_serve_restarts_with_the_exercise_a_page_chose_on_the_same_port():
    port = free_port()
    command = [sys.executable, "-c", "from davinci_sim.cli import main; raise SystemExit(main())",
               "serve", "--scene", "psm1_ecm_mtmr", "--task", "seed_path", "--no-server",
               "--images", "none", "--web-port", str(port), "--no-bedside",
               "--no-records"]  # fmt: skip
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               text=True, env=dict(os.environ))  # fmt: skip
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(process.stdout), daemon=True)
    reader.start()

    def wait_for(text: str, count: int = 1, timeout: float = 180.0) -> None:
        end = time.monotonic() + timeout
        while sum(text in line for line in list(lines)) < count:
            assert process.poll() is None, "".join(lines)
            assert time.monotonic() < end, f"no {text!r} in {''.join(lines)}"
            time.sleep(0.2)

    try:
        wait_for("web console: ")
        with connect(f"ws://127.0.0.1:{port}/ws", open_timeout=20) as ws:
            hello = json.loads(ws.recv(timeout=20))
            assert hello["task"]["name"] == "seed_path" and "needle_targeting" in hello["exercises"]
            ws.send(json.dumps({"op": "hello"}))
            ws.send(json.dumps({"op": "control", "take": True}))
            messages_until(ws, "control")
            ws.send(json.dumps({"op": "exercise", "task": "needle_targeting"}))
            assert messages_until(ws, "exercise")["task"] == "needle_targeting"
        wait_for("switching to the exercise needle_targeting")
        wait_for("web console: ", count=2)
        with connect(f"ws://127.0.0.1:{port}/ws", open_timeout=20) as ws:
            assert json.loads(ws.recv(timeout=20))["task"]["name"] == "needle_targeting"
    finally:
        process.send_signal(signal.SIGINT)
        code = process.wait(60)
        reader.join(10)
    assert code == 0, "".join(lines)
    assert sum("switching" in line for line in lines) == 1  # Ctrl-C stops for good
