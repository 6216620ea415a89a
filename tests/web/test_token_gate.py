"""The token gate in front of the 3-D view: without the page's token nothing reaches the
server behind it; with it, a browser's requests and websocket pass through unchanged."""

from __future__ import annotations

import http.client
import threading
import types
from urllib.parse import quote

import pytest
from websockets.sync.client import connect
from websockets.sync.server import serve

from davinci_sim.system import SystemDescription, scene_model
from davinci_sim.web.app import start_bedside
from davinci_sim.web.server import WebOptions
from davinci_sim.web.token_gate import TokenGate

TOKEN = "s3cret token/é"


@pytest.fixture
def upstream():
    """A loopback server like viser's: a page at any path, an echoing websocket; it counts
    what reached it."""
    seen: list[str] = []

    def page(connection, request):
        seen.append(request.path)
        if request.headers.get("Upgrade", "").lower() != "websocket":
            return connection.respond(200, f"page {request.path}\n")
        return None

    def echo(ws):
        for message in ws:
            ws.send(message)

    with serve(echo, "127.0.0.1", 0, process_request=page) as server:
        thread = threading.Thread(target=server.serve_forever, daemon=True)
        thread.start()
        yield server.socket.getsockname()[1], seen
        server.shutdown()
    thread.join(10)


@pytest.fixture
def gate(upstream):
    port, _ = upstream
    with TokenGate(port, TOKEN, "127.0.0.1") as gate:
        yield gate


def get(gate: TokenGate, path: str, cookie: str | None = None):
    conn = http.client.HTTPConnection("127.0.0.1", gate.port, timeout=10)
    conn.request("GET", path, headers={"Cookie": cookie} if cookie else {})
    response = conn.getresponse()
    body = response.read().decode()
    conn.close()
    return response, body


def session_cookie(gate: TokenGate) -> str:
    response, _ = get(gate, f"/?token={quote(TOKEN)}")
    return response.getheader("Set-Cookie").split(";")[0]


def test_without_the_token_nothing_reaches_the_server(gate, upstream):
    _, seen = upstream
    for path in ("/", "/?token=wrong", "/assets/app.js", f"/?token={quote(TOKEN)}x"):
        response, body = get(gate, path)
        assert response.status == 403 and "token" in body
    response, _ = get(gate, "/", cookie=f"{gate.cookie_name}=guessed")
    assert response.status == 403
    with pytest.raises(Exception, match="403"):
        connect(f"ws://127.0.0.1:{gate.port}/", open_timeout=10)
    assert seen == []
    assert gate.refused == 6


def test_the_token_sets_a_session_cookie_and_leaves_the_address(gate, upstream):
    _, seen = upstream
    response, _ = get(gate, f"/view?a=1&token={quote(TOKEN)}&b=2")
    assert response.status == 303
    assert response.getheader("Location") == "/view?a=1&b=2"
    cookie = response.getheader("Set-Cookie")
    assert cookie.startswith(f"{gate.cookie_name}=")
    assert "HttpOnly" in cookie and "SameSite=Strict" in cookie
    assert TOKEN not in cookie and quote(TOKEN) not in cookie
    assert seen == []  # (the gate answered itself)


def test_with_the_session_pages_and_the_websocket_pass_through(gate, upstream):
    _, seen = upstream
    cookie = session_cookie(gate)
    response, body = get(gate, "/assets/app.js?v=3", cookie=f"other=1; {cookie}")
    assert (response.status, body) == (200, "page /assets/app.js?v=3\n")
    with connect(f"ws://127.0.0.1:{gate.port}/", additional_headers={"Cookie": cookie},
                 open_timeout=10) as ws:  # fmt: skip
        ws.send("hello")
        assert ws.recv(timeout=10) == "hello"
        ws.send(b"\x00" * 300_000)  # (larger than one read of the gate)
        assert ws.recv(timeout=10) == b"\x00" * 300_000
    assert seen == ["/assets/app.js?v=3", "/"]


def test_a_malformed_request_is_refused_and_the_gate_goes_on(gate):
    import socket

    with socket.create_connection(("127.0.0.1", gate.port), timeout=10) as s:
        s.sendall(b"NONSENSE\r\n\r\n")
        assert s.recv(100).startswith(b"HTTP/1.1 400")
    response, _ = get(gate, "/")
    assert response.status == 403


def test_a_gate_needs_a_token():
    with pytest.raises(ValueError, match="token"):
        TokenGate(1, "", "127.0.0.1")


def test_the_3d_view_is_gated_beyond_loopback_only():
    description = SystemDescription("psm1_ecm_mtmr")
    system = types.SimpleNamespace(model_source=lambda: scene_model(description), handle=None)
    view, gate = start_bedside(system, WebOptions(host="127.0.0.1", port=0))
    try:
        assert view is not None and gate is None
    finally:
        view.stop()
    view, gate = start_bedside(system, WebOptions(host="0.0.0.0", port=0, token=TOKEN))
    try:
        assert view.host == "127.0.0.1"  # (viser itself stays on loopback)
        assert gate is not None and gate.port != view.port
        assert gate.url == f"http://127.0.0.1:{gate.port}/"  # (bound everywhere: shown here)
        response, _ = get(gate, "/")
        assert response.status == 403
        response, body = get(gate, "/", cookie=session_cookie(gate))
        assert response.status == 200 and "<title>Viser</title>" in body
    finally:
        gate.stop()
        view.stop()
