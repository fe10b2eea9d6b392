"""The web server of the live page: Starlette on uvicorn, one WebSocket per browser tab.

* ``GET /``: the page (static HTML, JavaScript and uPlot shipped in the package: it works
  with no internet); ``GET /static/...``; ``GET /api/state``: the whole session so far as
  JSON (what a new tab gets first); ``GET /api/stats``: the server's own timing (ticks,
  work per tick, updates sent and skipped per tab); ``WS /ws``: the updates.
* Updates are built per client from its cursor (:meth:`DashboardModel.update`), at most
  :data:`UPDATE_HZ` per second, and each client has at most one message in flight: a tab
  that stalls is skipped until its socket drains, then gets the current envelope (the bins
  changed since its cursor), never a backlog; the session never waits for a browser.
* Access: bound to 127.0.0.1 by default. With a token (needed for any other address) every
  request must carry it (``?token=`` once, then an HttpOnly cookie); without it: 403.
  The page only reads: there is no request that changes the session.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import errno
import hmac
import json
import math
import socket
import threading
import time
from importlib import resources
from typing import TYPE_CHECKING, Any

from starlette.applications import Starlette
from starlette.responses import FileResponse, JSONResponse, PlainTextResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

if TYPE_CHECKING:
    from collections.abc import AsyncIterator

    from starlette.requests import Request
    from starlette.types import ASGIApp, Receive, Scope, Send

    from rv_te_bench.dashboard.model import DashboardModel

__all__ = ['UPDATE_HZ', 'HttpServer', 'PortInUseError', 'bind_socket', 'create_app']

#: Updates per second to each client (screen updates: the page draws each one).
UPDATE_HZ = 25.0
#: A client with nothing new still gets the status this often [s].
HEARTBEAT_S = 1.0
COOKIE = 'rv_te_dashboard_token'
#: Keys whose lists the model has made JSON-safe already (large: not walked again).
_CLEAN_KEYS = frozenset({'cols', 'min', 'max', 'points'})
SECURITY_HEADERS = {
    'Content-Security-Policy': "default-src 'self'; script-src 'self'; style-src 'self'; "
                               "img-src 'self' data:; connect-src 'self'; "
                               "frame-ancestors 'none'; base-uri 'none'",
    'X-Content-Type-Options': 'nosniff', 'Referrer-Policy': 'no-referrer',
    'Cache-Control': 'no-store'}


class PortInUseError(OSError):
    """The page's port is taken."""


def static_dir() -> str:
    """The packaged page (index.html, app.js, uPlot and its licence)."""
    return str(resources.files('rv_te_bench.dashboard').joinpath('static'))


def bind_socket(host: str, port: int) -> socket.socket:
    """A listening TCP socket on ``host:port`` (port 0: any free port).

    Raises:
        PortInUseError: The port is taken.
        OSError: Another reason (no such address).
    """
    family = socket.AF_INET6 if ':' in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
    except OSError as exc:
        sock.close()
        if exc.errno == errno.EADDRINUSE:
            msg = f'port {port} on {host} is in use'
            raise PortInUseError(msg) from None
        raise
    sock.listen(64)
    sock.setblocking(False)
    return sock


def jsonable(obj: Any) -> Any:
    """NaN / inf -> None in a small structure (JSON has no NaN)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: (v if k in _CLEAN_KEYS else jsonable(v)) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [jsonable(v) for v in obj]
    return obj


def dumps(update: dict[str, Any]) -> str:
    """One update as compact JSON."""
    return json.dumps(jsonable(update), separators=(',', ':'), allow_nan=False)


class _TokenGate:
    """ASGI middleware: 403 unless the request carries the token (query or cookie)."""

    def __init__(self, app: ASGIApp, token: str | None) -> None:
        self.app = app
        self.token = token

    def _ok(self, scope: Scope) -> tuple[bool, bool]:
        """(allowed, came in the query string)."""
        if not self.token:
            return True, False
        from urllib.parse import parse_qs

        query = parse_qs(scope.get('query_string', b'').decode('latin-1'))
        for given in query.get('token', []):
            if hmac.compare_digest(given.encode(), self.token.encode()):
                return True, True
        for name, value in scope.get('headers', []):
            if name == b'cookie':
                for part in value.decode('latin-1').split(';'):
                    k, _, v = part.strip().partition('=')
                    if k == COOKIE and hmac.compare_digest(v.encode(), self.token.encode()):
                        return True, False
        return False, False

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope['type'] not in {'http', 'websocket'}:
            await self.app(scope, receive, send)
            return
        ok, in_query = self._ok(scope)
        if not ok:
            if scope['type'] == 'websocket':
                await send({'type': 'websocket.close', 'code': 1008})   # HTTP 403
                return
            await PlainTextResponse('403: this dashboard needs its access token (the link '
                                    'printed when it started)', status_code=403)(
                scope, receive, send)
            return

        async def send_with_headers(message: dict[str, Any]) -> None:
            if message['type'] == 'http.response.start':
                headers = list(message.get('headers', []))
                headers += [(k.lower().encode(), v.encode())
                            for k, v in SECURITY_HEADERS.items()]
                if in_query:
                    headers.append((b'set-cookie', f'{COOKIE}={self.token}; HttpOnly; '
                                    'SameSite=Strict; Path=/'.encode()))
                message = {**message, 'headers': headers}
            await send(message)

        await self.app(scope, receive, send_with_headers)


class _Client:
    def __init__(self, ws: WebSocket) -> None:
        self.ws = ws
        self.cursor: dict[str, Any] | None = None
        self.queue: asyncio.Queue[str] = asyncio.Queue(maxsize=1)
        self.last_sent = 0.0
        self.sent = 0
        self.skipped = 0


class Hub:
    """The connected tabs and the loop that sends each its update."""

    def __init__(self, model: DashboardModel) -> None:
        """No client yet."""
        self.model = model
        self.clients: set[_Client] = set()
        self.ticks = 0
        self.work_s: collections.deque[float] = collections.deque(maxlen=2000)
        self.gap_s: collections.deque[float] = collections.deque(maxlen=2000)

    async def run(self) -> None:
        """Fold the samples in and update every ready client, UPDATE_HZ times a second."""
        period = 1.0 / UPDATE_HZ
        due = last = time.monotonic()
        while True:
            start = time.monotonic()
            self.gap_s.append(start - last)
            last = start
            self.model.fold()
            self.ticks += 1
            for c in list(self.clients):
                if not c.queue.empty():
                    c.skipped += 1   # still sending the previous one: it gets fresh data later
                    continue
                if (c.cursor is not None and c.cursor.get('gen') == self.model.gen
                        and start - c.last_sent < HEARTBEAT_S):
                    continue
                update, c.cursor = self.model.update(c.cursor)
                c.queue.put_nowait(dumps(update))
                c.last_sent = start
            now = time.monotonic()
            self.work_s.append(now - start)
            # on a fixed grid of 1/UPDATE_HZ: a tick that woke late (a busy machine) does not
            # push the next one later too; ticks missed altogether are not made up in a burst
            due = max(due + period, now - period / 2)
            await asyncio.sleep(max(due - now, 0.002))

    def stats(self) -> dict[str, Any]:
        """Where the server's time goes (the benchmark reads it): ticks so far, the time
        of a tick's work (fold + every client's update) [ms], the longest time between
        two ticks of the last 250, per client the updates sent and the ticks skipped
        because its previous update was still being sent."""
        work = sorted(self.work_s)
        pick = (lambda q: 1e3 * work[min(int(q * len(work)), len(work) - 1)]) if work else (
            lambda _q: None)
        gaps = list(self.gap_s)[-250:]
        return {'ticks': self.ticks, 'update_hz': UPDATE_HZ, 'work_ms_p50': pick(0.5),
                'work_ms_p95': pick(0.95), 'work_ms_max': pick(1.0),
                'gap_ms_max_last_250': 1e3 * max(gaps) if gaps else None,
                'clients': [{'sent': c.sent, 'skipped': c.skipped} for c in self.clients]}

    async def serve(self, ws: WebSocket) -> None:
        """One tab: send its updates until it goes."""
        await ws.accept()
        client = _Client(ws)
        self.clients.add(client)

        async def sender() -> None:
            while True:
                text = await client.queue.get()
                await ws.send_text(text)
                client.sent += 1
                client.queue.task_done()

        task = asyncio.create_task(sender())
        try:
            while True:
                await ws.receive_text()   # the page sends nothing that changes anything
        except WebSocketDisconnect:
            pass
        finally:
            self.clients.discard(client)
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task


def create_app(model: DashboardModel, *, token: str | None = None) -> tuple[ASGIApp, Hub]:
    """The ASGI app (behind the token gate) and its hub."""
    hub = Hub(model)
    root = static_dir()

    async def index(_request: Request) -> Response:
        return FileResponse(f'{root}/index.html', media_type='text/html')

    async def state(_request: Request) -> Response:
        update, _ = model.update(None)
        return JSONResponse(jsonable(update))

    async def stats(_request: Request) -> Response:
        return JSONResponse(hub.stats())

    async def ws(websocket: WebSocket) -> None:
        await hub.serve(websocket)

    @contextlib.asynccontextmanager
    async def lifespan(_app: Starlette) -> AsyncIterator[None]:
        task = asyncio.create_task(hub.run())
        try:
            yield
        finally:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task

    app = Starlette(routes=[Route('/', index), Route('/api/state', state),
                            Route('/api/stats', stats),
                            WebSocketRoute('/ws', ws),
                            Mount('/static', app=StaticFiles(directory=root), name='static')],
                    lifespan=lifespan)
    return _TokenGate(app, token), hub


class HttpServer:
    """uvicorn serving the app on a bound socket, in a thread of its own."""

    def __init__(self, app: ASGIApp, sock: socket.socket) -> None:
        """Prepare; :meth:`start` runs it."""
        import uvicorn

        self.sock = sock
        config = uvicorn.Config(app, log_level='warning', ws='websockets-sansio',
                                lifespan='on', access_log=False)
        self.server = uvicorn.Server(config)
        self.thread = threading.Thread(target=self._run, name='dashboard-http', daemon=True)

    def _run(self) -> None:
        asyncio.run(self.server.serve(sockets=[self.sock]))

    def start(self, timeout_s: float = 10.0) -> None:
        """Start serving; returns once uvicorn is up."""
        self.thread.start()
        end = time.monotonic() + timeout_s
        while not self.server.started and self.thread.is_alive() and time.monotonic() < end:
            time.sleep(0.02)

    def stop(self) -> None:
        """Stop serving (open tabs keep what they show)."""
        self.server.should_exit = True
        self.thread.join(timeout=5.0)
        with contextlib.suppress(OSError):
            self.sock.close()
