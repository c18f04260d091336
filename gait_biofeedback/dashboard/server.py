"""HTTP + websocket server of the clinician's dashboard, in its own thread and asyncio event loop.

One port serves both: plain HTTP GETs of the static files (``gait_biofeedback/dashboard/``) through the
``process_request`` hook of the ``websockets`` library, and the websocket endpoint ``/ws``. The ROS side
never waits on it: it hands over two callables,

* ``build_frame() -> dict | None``: called in the server thread at ``frame_rate_hz`` Hz while a page is
  connected; it must only read/drain thread-safe structures (the node's latest-state references and
  deques) and return the JSON-able frame (None: nothing new);
* ``on_message(dict)``: called in the server thread for each command from a page allowed to send
  commands; it must only queue it.

Security (the page shows and drives a patient's session):

* it binds the given host only (default 127.0.0.1);
* every request must name this server in its ``Host`` header (``127.0.0.1:<port>``, ``localhost:<port>``
  or ``[::1]:<port>`` for a loopback bind; ``<host>:<port>`` otherwise), so a web page that rebinds
  its own DNS name to 127.0.0.1 cannot reach it; the websocket handshake must carry no ``Origin`` or
  the origin of this server, so no other web page can open it. Refusals are HTTP 403, logged at most
  once per ``REFUSAL_LOG_PERIOD`` (the first at once, then one line with the count of those since),
  the offending value cut to 80 characters: a flood of refused requests grows neither memory nor log;
* at most ``max_clients`` read-only pages and :data:`COMMANDER_SLOTS` pages with the token are
  connected at once (another websocket handshake gets HTTP 503): idle read-only pages cannot lock the
  clinician out;
* commands need the session's token: a random string made at start (:attr:`DashboardServer.token`),
  known only to whoever started the session: the node prints the link with it on the terminal and
  writes it to an owner-only file, never to the ROS log (``http://127.0.0.1:8080/?token=...``, as
  Jupyter does). The page passes it on in the websocket URL; a connection without it is read-only: it
  receives frames, and every command gets a refusal reply; a wrong one is counted
  (:attr:`DashboardServer.token_failures`) and logged at the refusals' rate.

Frames go to every page with ``websockets.broadcast`` (non-blocking); a page whose send buffer is above
``max_buffer`` bytes skips frames until it catches up, so a stalled browser cannot grow memory.
``port`` 0 picks a free port; a busy port is followed by the next free one of ``port + 1 ... port + 20``
(read :attr:`DashboardServer.port`, said in the log).
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import hmac
import json
import logging
import math
import mimetypes
import secrets
import threading
import time
from collections.abc import Callable, Sequence
from http import HTTPStatus
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

from websockets.asyncio.server import ServerConnection, broadcast, serve
from websockets.datastructures import Headers
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response

from gait_biofeedback.core.safe_yaml import shown

STATIC_DIR = Path(__file__).resolve().parent
WEBSOCKET_PATH = "/ws"
LOOPBACK_NAMES = ("127.0.0.1", "localhost", "[::1]")
WILDCARDS = ("0.0.0.0", "::", "")


def _origins(hosts: set[str]) -> set[str]:
    """The page origins of ``hosts`` (host:port): http and https, without a scheme's default port."""
    out = {f"{scheme}://{h}" for h in hosts for scheme in ("http", "https")}
    out |= {f"http://{h[:-3]}" for h in hosts if h.endswith(":80")}
    out |= {f"https://{h[:-4]}" for h in hosts if h.endswith(":443")}
    return out


def _bracketed(host: str) -> str:
    """An IPv6 address as a Host header writes it (``[::1]``)."""
    return f"[{host}]" if ":" in host and not host.startswith("[") else host
PORT_TRIES = 20
REFUSAL_LOG_PERIOD = 10.0
"""s: at most one log line about refused requests this often (module docstring)."""
COMMANDER_SLOTS = 4
"""Pages with the session's token connected at most, apart from the read-only ones' ``max_clients``."""
MAX_CLIENTS = 16
_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
          ".css": "text/css; charset=utf-8", ".png": "image/png", ".svg": "image/svg+xml"}


class DashboardServer:
    """Static files + websocket frames for the dashboard (see module docstring)."""

    def __init__(self, build_frame: Callable[[], dict | None], on_message: Callable[[dict], None],
                 hello: Callable[[], dict], host: str = "127.0.0.1", port: int = 8080,
                 frame_rate_hz: float = 30.0, static_dir: Path = STATIC_DIR, max_buffer: int = 1 << 20,
                 logger: Any = None, token: str | None = None, allowed_hosts: Sequence[str] = (),
                 max_clients: int = MAX_CLIENTS) -> None:
        self.build_frame = build_frame
        self.on_message = on_message
        self.hello = hello
        self.host = host
        self.extra_hosts = tuple(allowed_hosts)
        self.requested_port = int(port)
        self.period = 1.0 / max(float(frame_rate_hz), 1.0)
        self.static_dir = Path(static_dir).resolve()
        self.max_buffer = int(max_buffer)
        self.max_clients = int(max_clients)
        self.log = logger
        self.token = token or secrets.token_urlsafe(18)
        self.port: int | None = None
        self.frames_sent = 0
        self.frames_skipped = 0
        self.refused = 0
        self.token_failures = 0
        self.error: BaseException | None = None
        self._clients: set[ServerConnection] = set()
        self._commanders: set[ServerConnection] = set()
        self._refusal_logged_at = -math.inf  # monotonic time of the last refusal line
        self._refusals_unlogged = 0  # refusals since that line
        self._ready = threading.Event()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._thread: threading.Thread | None = None
        self._final: dict | None = None

    @property
    def clients(self) -> int:
        return len(self._clients)

    @property
    def url(self) -> str:
        """The link that may send commands (it carries the token)."""
        host = "127.0.0.1" if self.host in WILDCARDS else _bracketed(self.host)
        return f"http://{host}:{self.port}/?token={self.token}"

    def _allowed_hosts(self) -> set[str]:
        """``Host`` values of this server, lower case: its address (loopback names for a loopback or
        wildcard bind) and ``allowed_hosts``, each with this port unless it names its own."""
        loopback = self.host in LOOPBACK_NAMES or self.host.startswith("127.") or self.host in WILDCARDS
        names = [*(LOOPBACK_NAMES if loopback else ()), _bracketed(self.host), *self.extra_hosts]
        out = set()
        for name in (n.lower() for n in names):
            has_port = name.rsplit(":", 1)[-1].isdigit() and not name.endswith("]")
            out.add(name if has_port else f"{name}:{self.port}")
        return out

    def start(self, timeout: float = 5.0) -> int:
        """Start the server thread; return the bound port (raises if binding failed)."""
        self._thread = threading.Thread(target=self._run, name="dashboard-server", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout):
            raise TimeoutError("dashboard server did not start")
        if self.error is not None:
            raise RuntimeError(f"dashboard server: {self.error}") from self.error
        return int(self.port)

    def stop(self, timeout: float = 3.0, final: dict | None = None) -> None:
        """Close every connection and end the thread; ``final``: a last message sent to every page
        first (the node's "session ended", so the page keeps its values and says so)."""
        self._final = final
        if self._loop is not None and self._stop is not None and not self._loop.is_closed():
            with contextlib.suppress(RuntimeError):  # the loop has just closed
                self._loop.call_soon_threadsafe(self._stop.set)
        if self._thread is not None:
            self._thread.join(timeout)

    # -- server thread -------------------------------------------------------------------------------

    def _run(self) -> None:
        try:
            asyncio.run(self._main())
        except BaseException as exc:  # reported by start() or logged
            self.error = exc
            self._ready.set()
            if self.log is not None:
                self.log.error(f"dashboard server stopped: {exc}")

    async def _serve(self):
        """Bind the requested port, or the next free one when it is busy."""
        ports = [self.requested_port] if self.requested_port == 0 else [
            self.requested_port + k for k in range(PORT_TRIES + 1) if self.requested_port + k < 65536]
        for port in ports:
            try:
                return await serve(self._handler, self.host, port, process_request=self._http,
                                   max_size=1 << 16, compression=None)
            except OSError as exc:
                if exc.errno != errno.EADDRINUSE or port == ports[-1]:
                    raise OSError(f"cannot serve the dashboard on {self.host}:{port} ({exc.strerror}): set "
                                  "the biofeedback parameter 'port' to a free port (0 = any)") from None
        raise AssertionError("unreachable")

    async def _main(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        # websockets logs every plain HTTP request it answers at INFO level: keep it quiet
        logging.getLogger("websockets").setLevel(logging.WARNING)
        server = await self._serve()
        async with server:
            self.port = server.sockets[0].getsockname()[1]
            if self.requested_port and self.port != self.requested_port and self.log is not None:
                self.log.warning(f"port {self.requested_port} is busy: the dashboard is on port {self.port} "
                                 "instead (parameter 'port' of biofeedback)")
            self._ready.set()
            next_t = time.monotonic()
            while not self._stop.is_set():
                next_t += self.period
                if self._clients:
                    self._send_frame()
                if self._refusals_unlogged:
                    self._log_refusal(None)
                delay = next_t - time.monotonic()
                if delay < 0:  # fell behind: do not burst to catch up
                    next_t = time.monotonic()
                    delay = 0.0
                await asyncio.sleep(delay)
            if self._final is not None and self._clients:
                self._send_frame()  # what was queued before the end
                text = json.dumps(self._final, separators=(",", ":"), allow_nan=False)
                broadcast(list(self._clients), text)
                await asyncio.sleep(0.05)  # let the transports write it before the close frames
            server.close()

    def _send_frame(self) -> None:
        try:
            frame = self.build_frame()
        except Exception as exc:  # a bug in a frame must not kill the server
            if self.log is not None:
                self.log.error(f"dashboard frame failed: {exc!r}")
            return
        if frame is None:
            return
        text = json.dumps(frame, separators=(",", ":"), allow_nan=False)
        ready = []
        for ws in self._clients:
            transport = ws.transport
            if transport is not None and transport.get_write_buffer_size() > self.max_buffer:
                self.frames_skipped += 1
            else:
                ready.append(ws)
        if ready:
            broadcast(ready, text)
            self.frames_sent += 1

    def _given_token(self, request: Request) -> str:
        return parse_qs(urlsplit(request.path).query).get("token", [""])[0]

    def _has_token(self, request: Request) -> bool:
        return hmac.compare_digest(self._given_token(request).encode(), self.token.encode())

    def _may_command(self, request: Request) -> bool:
        """Whether the page's link carries the session's token. A wrong one (a guess) is counted in
        :attr:`token_failures` and logged at the refusals' bounded rate; no token is a read-only view."""
        if self._has_token(request):
            return True
        given = self._given_token(request)
        if given:
            self.token_failures += 1
            self._refusals_unlogged += 1
            self._log_refusal(f"a page with a wrong command token ({self.token_failures} so far); it is "
                              "shown read-only")
        return False

    async def _handler(self, ws: ServerConnection) -> None:
        self._clients.add(ws)
        commander = ws.request is not None and self._may_command(ws.request)
        if commander:
            self._commanders.add(ws)
        try:
            hello = {**self.hello(), "read_only": not commander}
            await ws.send(json.dumps(hello, separators=(",", ":"), allow_nan=False))
            async for raw in ws:
                try:
                    if not isinstance(raw, str):
                        raise ValueError("a binary frame: commands are JSON text")
                    message = json.loads(raw)
                    if not isinstance(message, dict):
                        raise ValueError("expected a JSON object")
                except ValueError as exc:
                    await ws.send(json.dumps({"type": "error", "message": f"bad message: {exc}"}))
                    continue
                if not commander:
                    self.refused += 1
                    await ws.send(json.dumps({
                        "type": "reply", "action": str(message.get("action", "?"))[:40], "success": False,
                        "message": "read-only view: open the dashboard with the link printed where the "
                                   "session was started (…/?token=…, also in the session folder's "
                                   "dashboard_url.txt) to send commands"}))
                    continue
                self.on_message(message)
        except ConnectionClosed:
            pass
        finally:
            self._clients.discard(ws)
            self._commanders.discard(ws)

    def _refuse(self, connection: ServerConnection, why: str,
                status: HTTPStatus = HTTPStatus.FORBIDDEN) -> Response:
        self.refused += 1
        self._refusals_unlogged += 1
        self._log_refusal(why)
        return connection.respond(status, f"refused: {why}\n")

    def _log_refusal(self, why: str | None) -> None:
        """Log ``why`` (None: only the count of refusals not logged yet) unless a refusal line was
        logged less than ``REFUSAL_LOG_PERIOD`` ago (module docstring)."""
        now = time.monotonic()
        if self.log is None or now - self._refusal_logged_at < REFUSAL_LOG_PERIOD:
            return
        count, self._refusals_unlogged = self._refusals_unlogged, 0
        self._refusal_logged_at = now
        if why is None:
            self.log.warning(f"dashboard refused {count} more request(s) since the last such line")
        else:
            more = f" ({count - 1} more refused since the last such line)" if count > 1 else ""
            self.log.warning(f"dashboard refused a request: {why}{more}")

    def _http(self, connection: ServerConnection, request: Request) -> Response | None:
        hosts = request.headers.get_all("Host")
        if len(hosts) > 1:
            return self._refuse(connection, "more than one Host header")
        host = hosts[0] if hosts else ""
        allowed = self._allowed_hosts()
        if host.lower() not in allowed:
            return self._refuse(connection, f"Host {shown(host)} is not this dashboard (a page rebinding "
                                            "its address to this machine?)")
        path = urlsplit(request.path).path
        if path == WEBSOCKET_PATH:
            origin = request.headers.get("Origin")
            if origin is not None and origin.lower() not in _origins(allowed):
                return self._refuse(connection, f"websocket from the web page of origin {shown(origin)}")
            # read-only pages cannot crowd out the clinician's: pages with the token have slots of their own
            commanding = self._has_token(request)
            full = (len(self._commanders) >= COMMANDER_SLOTS if commanding
                    else len(self._clients) - len(self._commanders) >= self.max_clients)
            if full:
                return self._refuse(connection, f"{COMMANDER_SLOTS if commanding else self.max_clients} "
                                    f"{'command' if commanding else 'read-only'} pages are connected already",
                                    HTTPStatus.SERVICE_UNAVAILABLE)
            return None  # go on with the websocket handshake
        name = "index.html" if path in ("", "/") else path.lstrip("/")
        file = (self.static_dir / name).resolve()
        if self.static_dir not in file.parents or not file.is_file() or file.suffix not in _TYPES:
            return connection.respond(HTTPStatus.NOT_FOUND, "not found\n")
        body = file.read_bytes()
        ctype = _TYPES.get(file.suffix) or mimetypes.guess_type(file.name)[0] or "application/octet-stream"
        headers = Headers([("Content-Type", ctype), ("Content-Length", str(len(body))),
                           ("Cache-Control", "no-cache"), ("Connection", "close"),
                           ("X-Frame-Options", "DENY"), ("Referrer-Policy", "no-referrer")])
        return Response(200, "OK", headers, body)
