"""The 3-D view behind the page's token: :class:`TokenGate`, a gate in front of a loopback
HTTP and websocket server (viser's, which has no authentication of its own).

The gate listens where the page is served (beyond loopback) and passes a connection on to
the server, unchanged, byte for byte, only once its first request proved the token:

- a request carrying ``?token=`` (the page's own token, as the page's address carries it)
  is answered with a redirect to the same address without it, setting a cookie with a
  random session key (``HttpOnly``, ``SameSite=Strict``, named after the gate's port: a
  browser sends a host's cookies to all its ports);
- a request with that cookie (the page's assets, the view's websocket) is passed on;
- any other is refused with 403 and nothing reaches the server.

A connection passed on stays passed on: HTTP keep-alive and the websocket run through it
untouched, so the gate needs no knowledge of the server's protocol.
"""

from __future__ import annotations

import asyncio
import hmac
import logging
import secrets
import threading
from http.cookies import CookieError, SimpleCookie
from urllib.parse import parse_qsl, urlencode, urlsplit, urlunsplit

from davinci_sim.web.hosts import shown_host

log = logging.getLogger("davinci_sim.web")

HEAD_LIMIT_BYTES = 64 * 1024
"""A request head longer than this is refused (431)."""
HEAD_TIMEOUT_S = 10.0
"""A connection that sends no complete request head within this is closed."""
CHUNK_BYTES = 256 * 1024


class TokenGate:
    """Serve ``host:port`` (0: a free port) as the loopback server at ``upstream_port``,
    for clients that proved ``token``. :meth:`start` and :meth:`stop`; a context manager."""

    def __init__(self, upstream_port: int, token: str, host: str, port: int = 0) -> None:
        if not token:
            raise ValueError("a token gate needs a non-empty token")
        self.upstream = ("127.0.0.1", int(upstream_port))
        self.host, self._requested_port = host, int(port)
        self._token = token.encode()
        self._session = secrets.token_urlsafe(32)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: asyncio.AbstractServer | None = None
        self._thread: threading.Thread | None = None
        self.port: int | None = None
        self.refused = 0
        """Requests refused so far (wrong or missing token or cookie)."""

    @property
    def url(self) -> str:
        """The gate's address (after :meth:`start`)."""
        return f"http://{shown_host(self.host)}:{self.port}/"

    @property
    def cookie_name(self) -> str:
        return f"davinci_sim_view_{self.port}"

    def start(self) -> TokenGate:
        ready = threading.Event()
        failure: list[BaseException] = []

        def run() -> None:
            loop = asyncio.new_event_loop()
            self._loop = loop
            try:
                self._server = loop.run_until_complete(
                    asyncio.start_server(
                        self._serve, self.host, self._requested_port, limit=HEAD_LIMIT_BYTES
                    )
                )
                self.port = int(self._server.sockets[0].getsockname()[1])
            except BaseException as e:  # (reported to start's caller)
                failure.append(e)
                ready.set()
                loop.close()
                return
            ready.set()
            try:
                loop.run_forever()
            finally:
                loop.close()

        self._thread = threading.Thread(target=run, name="token-gate", daemon=True)
        self._thread.start()
        ready.wait()
        if failure:
            raise failure[0]
        return self

    def stop(self) -> None:
        loop, server = self._loop, self._server
        if loop is None or server is None or self._thread is None:
            return

        async def close() -> None:
            server.close()
            for task in asyncio.all_tasks():
                if task is not asyncio.current_task():
                    task.cancel()
            loop.stop()

        asyncio.run_coroutine_threadsafe(close(), loop)
        self._thread.join(10)
        self._thread = self._server = None

    def __enter__(self) -> TokenGate:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    # ------------------------------------------------------------------ one connection
    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), timeout=HEAD_TIMEOUT_S)
        except asyncio.LimitOverrunError:
            await self._answer(writer, 431, "request head too long\n")
            return
        except (asyncio.IncompleteReadError, TimeoutError, ConnectionError):
            writer.close()
            return
        verdict = self._judge(head)
        if isinstance(verdict, bytes):  # an answer of the gate's own
            self.refused += verdict.startswith(b"HTTP/1.1 403")
            await self._send_and_close(writer, verdict)
            return
        try:
            up_reader, up_writer = await asyncio.open_connection(*self.upstream)
        except OSError:
            await self._answer(writer, 502, "the view's server is not running\n")
            return
        up_writer.write(head)
        await asyncio.gather(_pipe(reader, up_writer), _pipe(up_reader, writer))

    def _judge(self, head: bytes) -> bytes | None:
        """None to pass the connection on, or the gate's own answer (bytes)."""
        try:
            lines = head.decode("latin-1").split("\r\n")
            method, target, _version = lines[0].split(" ", 2)
        except ValueError:
            return _response(400, "malformed request\n")
        cookies: SimpleCookie = SimpleCookie()
        for line in lines[1:]:
            name, _, value = line.partition(":")
            if name.strip().lower() == "cookie":
                try:
                    cookies.load(value.strip())
                except CookieError:
                    pass
        held = cookies.get(self.cookie_name)
        if held is not None and hmac.compare_digest(held.value.encode(), self._session.encode()):
            return None
        url = urlsplit(target)
        query = parse_qsl(url.query, keep_blank_values=True)
        given = [v for k, v in query if k == "token"]
        if given and hmac.compare_digest(given[0].encode(), self._token):
            rest = urlencode([(k, v) for k, v in query if k != "token"])
            location = urlunsplit(("", "", url.path or "/", rest, ""))
            cookie = f"{self.cookie_name}={self._session}; HttpOnly; SameSite=Strict; Path=/"
            return _response(303, "", [("Location", location), ("Set-Cookie", cookie)])
        log.warning("3-D view: refused a %s request without the token", method)
        return _response(403, "wrong or missing token\n")

    async def _answer(self, writer: asyncio.StreamWriter, status: int, text: str) -> None:
        await self._send_and_close(writer, _response(status, text))

    @staticmethod
    async def _send_and_close(writer: asyncio.StreamWriter, data: bytes) -> None:
        try:
            writer.write(data)
            await writer.drain()
        except ConnectionError:
            pass
        finally:
            writer.close()


_REASONS = {303: "See Other", 400: "Bad Request", 403: "Forbidden", 431:
            "Request Header Fields Too Large", 502: "Bad Gateway"}  # fmt: skip


def _response(status: int, text: str, headers: list[tuple[str, str]] = ()) -> bytes:
    body = text.encode()
    lines = [f"HTTP/1.1 {status} {_REASONS[status]}", "Content-Type: text/plain; charset=utf-8",
             f"Content-Length: {len(body)}", "Connection: close", "Cache-Control: no-store",
             *(f"{k}: {v}" for k, v in headers)]  # fmt: skip
    return ("\r\n".join(lines) + "\r\n\r\n").encode("latin-1") + body


async def _pipe(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
    """Copy ``reader`` to ``writer`` until either side closes; then close ``writer``."""
    try:
        while chunk := await reader.read(CHUNK_BYTES):
            writer.write(chunk)
            await writer.drain()
    except (ConnectionError, asyncio.CancelledError):
        pass
    finally:
        try:
            writer.close()
        except RuntimeError:  # (a pipe left when its loop closed, closed as garbage)
            pass
