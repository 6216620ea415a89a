"""The web console and the trainee records: the page's trainee field sets whose attempts are
recorded, and the page shows the trainee's learning curves (only to a page with the token
when the console has one)."""

from __future__ import annotations

import io
import json
import time
import urllib.error
import urllib.request

import pytest
from PIL import Image
from websockets.sync.client import connect

from davinci_sim.records import MetricInfo, RecordsDB, records_part
from davinci_sim.system import SystemDescription, build_system
from davinci_sim.web.server import WebConsole, WebOptions


@pytest.fixture(scope="module")
def web(tmp_path_factory):
    path = tmp_path_factory.mktemp("records") / "records.sqlite3"
    with RecordsDB(path) as db:
        s = db.start_session("ana")
        for i in range(3):
            db.record_attempt(s, task="seed_path", metrics={"deviation_error": 0.003 - 0.001 * i},
                              info={"deviation_error": MetricInfo("m", "lower")})  # fmt: skip
    part = records_part("ana", path=path)
    part.task_name = "seed_path"  # (what the part learns from the task when serve starts it)
    system = build_system(SystemDescription(scene="psm1_ecm_mtmr", runner="thread"), start=True)
    open_web = WebConsole(system.handle, WebOptions(port=0), records=part).start()
    token_web = WebConsole(system.handle, WebOptions(port=0, token="s3cret"), records=part)
    token_web.start()
    yield open_web, token_web, part
    open_web.stop()
    token_web.stop()
    system.stop()


def next_op(ws, op: str, timeout: float = 10.0) -> dict:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        data = ws.recv(timeout=max(0.01, end - time.monotonic()))
        if isinstance(data, str) and json.loads(data).get("op") == op:
            return json.loads(data)
    raise AssertionError(f"no {op!r} message")


def get(url: str) -> tuple[int, bytes]:
    try:
        with urllib.request.urlopen(url, timeout=30) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.read()


def test_the_pages_trainee_is_whose_attempts_are_recorded(web):
    open_web, _, part = web
    with connect(f"ws://127.0.0.1:{open_web.port}/ws", open_timeout=10) as ws:
        assert next_op(ws, "hello")["trainee"] == "ana"  # the trainee serve was given
        ws.send(json.dumps({"op": "hello"}))
        ws.send(json.dumps({"op": "trainee", "name": "ben"}))
        assert next_op(ws, "trainee")["name"] == "ben" and part.trainee == "ben"
        ws.send(json.dumps({"op": "trainee", "name": "  "}))  # cleared: serve's trainee again
        assert next_op(ws, "trainee")["name"] == "ana" and part.trainee == "ana"
        ws.send(json.dumps({"op": "trainee", "name": "b\u200bx"}))  # not printable: refused
        assert "trainee" in next_op(ws, "error")["message"] and part.trainee == "ana"


def test_the_page_gets_the_trainees_learning_curves(web):
    open_web, _, part = web
    status, body = get(f"http://127.0.0.1:{open_web.port}/records/curve.png?n=1")
    assert status == 200 and Image.open(io.BytesIO(body)).format == "PNG"
    curve = Image.open(io.BytesIO(body)).size
    part.set_trainee("cy")  # no attempt yet: a note
    try:
        status, body = get(f"http://127.0.0.1:{open_web.port}/records/curve.png")
        assert status == 200 and Image.open(io.BytesIO(body)).size == (600, 50) != curve
    finally:
        part.set_trainee("ana")


def test_the_page_is_told_whether_there_are_records(web):
    open_web, _, _ = web
    with connect(f"ws://127.0.0.1:{open_web.port}/ws", open_timeout=10) as ws:
        assert next_op(ws, "hello")["records"] is True


def test_with_a_token_only_a_page_with_it_gets_the_curves(web):
    _, token_web, _ = web
    base = f"http://127.0.0.1:{token_web.port}/records/curve.png"
    assert get(base)[0] == 403
    assert get(base + "?token=wrong")[0] == 403
    status, body = get(base + "?token=s3cret")
    assert status == 200 and body.startswith(b"\x89PNG")


def test_a_trainee_changed_while_the_curves_draw_does_not_get_them_cached(tmp_path, monkeypatch):
    """The page changes the trainee while the learning curves are drawn (in a worker thread,
    here as the records file opens): the drawing is of the trainee it is cached for, so the
    first trainee's curves come back, not the other's "no attempt" note."""
    import davinci_sim.records.console as console

    path = tmp_path / "records.sqlite3"
    with RecordsDB(path) as db:
        s = db.start_session("ana")
        for i in range(2):
            db.record_attempt(s, task="seed_path", metrics={"deviation_error": 0.003 - 0.001 * i},
                              info={"deviation_error": MetricInfo("m", "lower")})  # fmt: skip
    part = records_part("ana", path=path)
    part.task_name = "seed_path"
    changed = []

    def open_while_the_page_changes_the_trainee(*args, **kwargs):
        if not changed:
            changed.append(part.set_trainee("ben"))  # what the page's trainee field does
        return RecordsDB(*args, **kwargs)

    monkeypatch.setattr(console, "RecordsDB", open_while_the_page_changes_the_trainee)
    first = part.curve_png()
    assert changed == ["ben"]
    part.set_trainee("ana")
    assert part.curve_png() == first  # ana's, from the cache
    assert Image.open(io.BytesIO(first)).size != (600, 50)  # her curves, not a note
