"""HTTP + websocket server of the clinician's dashboard, in its own thread and asyncio event loop.

One port serves both: plain HTTP GETs of the static files (``gait_biofeedback/dashboard/``) through the
``process_request`` hook of the ``websockets`` library, and the websocket endpoint ``/ws``. The ROS side
never waits on it: it hands over two callables,

* ``build_frame() -> dict | None``: called in the server thread at ``frame_rate`` Hz while a page is
  connected; it must only read/drain thread-safe structures (the node's latest-state references and
  deques) and return the JSON-able frame (None: nothing new);
* ``on_message(dict)``: called in the server thread for each message from a page; it must only queue it.

Frames go to every page with ``websockets.broadcast`` (non-blocking); a page whose send buffer is above
``max_buffer`` bytes skips frames until it catches up, so a stalled browser cannot grow memory. Binds the
given host only (default 127.0.0.1); ``port`` 0 picks a free port (read :attr:`DashboardServer.port`).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import mimetypes
import threading
import time
from collections.abc import Callable
from http import HTTPStatus
from pathlib import Path
from typing import Any

from websockets.asyncio.server import ServerConnection, broadcast, serve
from websockets.datastructures import Headers
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response

STATIC_DIR = Path(__file__).resolve().parent
WEBSOCKET_PATH = "/ws"
_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
          ".css": "text/css; charset=utf-8", ".png": "image/png", ".svg": "image/svg+xml"}


class DashboardServer:
    """Static files + websocket frames for the dashboard (see module docstring)."""

    def __init__(self, build_frame: Callable[[], dict | None], on_message: Callable[[dict], None],
                 hello: Callable[[], dict], host: str = "127.0.0.1", port: int = 8080,
                 frame_rate: float = 30.0, static_dir: Path = STATIC_DIR, max_buffer: int = 1 << 20,
                 logger: Any = None) -> None:
        self.build_frame = build_frame
        self.on_message = on_message
        self.hello = hello
        self.host = host
        self.requested_port = int(port)
        self.period = 1.0 / max(float(frame_rate), 1.0)
        self.static_dir = Path(static_dir).resolve()
        self.max_buffer = int(max_buffer)
        self.log = logger
        self.port: int | None = None
        self.frames_sent = 0
        self.frames_skipped = 0
        self.error: BaseException | None = None
        self._clients: set[ServerConnection] = set()
        self._ready = threading.Event()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._thread: threading.Thread | None = None

    @property
    def clients(self) -> int:
        return len(self._clients)

    def start(self, timeout: float = 5.0) -> int:
        """Start the server thread; return the bound port (raises if binding failed)."""
        self._thread = threading.Thread(target=self._run, name="dashboard-server", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout):
            raise TimeoutError("dashboard server did not start")
        if self.error is not None:
            raise RuntimeError(f"dashboard server: {self.error}") from self.error
        return int(self.port)

    def stop(self, timeout: float = 3.0) -> None:
        """Close every connection and end the thread."""
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

    async def _main(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        # websockets logs every plain HTTP request it answers at INFO level: keep it quiet
        logging.getLogger("websockets").setLevel(logging.WARNING)
        async with serve(self._handler, self.host, self.requested_port, process_request=self._http,
                         max_size=1 << 16, compression=None) as server:
            self.port = server.sockets[0].getsockname()[1]
            self._ready.set()
            next_t = time.monotonic()
            while not self._stop.is_set():
                next_t += self.period
                if self._clients:
                    self._send_frame()
                delay = next_t - time.monotonic()
                if delay < 0:  # fell behind: do not burst to catch up
                    next_t = time.monotonic()
                    delay = 0.0
                await asyncio.sleep(delay)
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

    async def _handler(self, ws: ServerConnection) -> None:
        self._clients.add(ws)
        try:
            await ws.send(json.dumps(self.hello(), separators=(",", ":"), allow_nan=False))
            async for raw in ws:
                try:
                    message = json.loads(raw)
                    if not isinstance(message, dict):
                        raise ValueError("expected a JSON object")
                except ValueError as exc:
                    await ws.send(json.dumps({"type": "error", "message": f"bad message: {exc}"}))
                    continue
                self.on_message(message)
        except ConnectionClosed:
            pass
        finally:
            self._clients.discard(ws)

    def _http(self, connection: ServerConnection, request: Request) -> Response | None:
        path = request.path.split("?", 1)[0]
        if path == WEBSOCKET_PATH:
            return None  # go on with the websocket handshake
        name = "index.html" if path in ("", "/") else path.lstrip("/")
        file = (self.static_dir / name).resolve()
        if self.static_dir not in file.parents or not file.is_file():
            return connection.respond(HTTPStatus.NOT_FOUND, "not found\n")
        body = file.read_bytes()
        ctype = _TYPES.get(file.suffix) or mimetypes.guess_type(file.name)[0] or "application/octet-stream"
        headers = Headers([("Content-Type", ctype), ("Content-Length", str(len(body))),
                           ("Cache-Control", "no-cache"), ("Connection", "close")])
        return Response(200, "OK", headers, body)
