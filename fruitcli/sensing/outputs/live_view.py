"""The live view of `fruit live --view [HOST:]PORT`: a page on the local machine that
shows the taxel activations as a heat map on the body's top view, the touches with
their session ids, the chamber pressures, frames per second and the baseline state.

Standard library only: `http.server.ThreadingHTTPServer` in a daemon thread serves

- ``/``: the page (``live_view.html`` next to this module, no framework);
- ``/layout``: JSON ``{"taxels": [[id, i, j, x_mm, y_mm], ...], "threshold_counts"}``;
- ``/state``: the latest state as JSON (see `ViewServer`);
- ``/events``: the same state as server-sent events, at most `RATE_HZ` a second while
  it changes (a comment line every `KEEPALIVE_S` otherwise).

The live loop never waits for the view: `state` is a callable that the server's threads
call to build each event from what the loop last published.
"""

from __future__ import annotations

import errno
import json
import socket
import threading
import time
from collections.abc import Callable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

from fruitcli.errors import FrameError

RATE_HZ = 10.0
KEEPALIVE_S = 5.0
PAGE = Path(__file__).with_name("live_view.html")


class _ServerV6(ThreadingHTTPServer):
    """The view's server on an IPv6 address."""

    address_family = socket.AF_INET6


class ViewServer:
    """Serve the view on (host, port) until `close`. `layout` is the /layout JSON (a
    dict); `state()` returns the current state dict: ``frame``, ``t_s``, ``fps``,
    ``baseline``, ``reconnects``, ``activation`` (counts per taxel, in layout order),
    ``touches`` (``id, x_mm, y_mm, z_mm, i, j, peak``), ``pressures`` ({chamber: kPa}),
    ``flags`` ({flag: [taxel ids]})."""

    def __init__(
        self, host: str, port: int, layout: dict, state: Callable[[], dict], option: str = "--view"
    ):
        self.layout = json.dumps(layout).encode()
        self.state = state
        self.stopping = threading.Event()
        self.page = PAGE.read_bytes()
        view = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args: object):  # no request log on stderr
                pass

            def do_GET(self):
                path = self.path.split("?")[0]
                try:
                    if path == "/":
                        self._send(view.page, "text/html; charset=utf-8")
                    elif path == "/layout":
                        self._send(view.layout, "application/json")
                    elif path == "/state":
                        self._send(view.state_json(), "application/json")
                    elif path == "/events":
                        view.events(self)
                    else:
                        self.send_error(404)
                except (BrokenPipeError, ConnectionResetError):
                    pass  # the browser went away

            def _send(self, body: bytes, kind: str):
                self.send_response(200)
                self.send_header("Content-Type", kind)
                self.send_header("Content-Length", str(len(body)))
                self.send_header("Cache-Control", "no-store")
                self.end_headers()
                self.wfile.write(body)

        where = f"{option} {host}:{port}"
        server: type[ThreadingHTTPServer] = ThreadingHTTPServer
        if ":" in host:  # an IPv6 address, e.g. --view [::1]:8080
            server = _ServerV6
        try:
            self.httpd = server((host, port), Handler)
        except socket.gaierror as exc:
            raise FrameError(f"{where}: host {host!r} does not resolve ({exc.strerror})") from None
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                raise FrameError(
                    f"{where}: port {port} is in use (another program "
                    "listens there; choose another port)"
                ) from None
            if exc.errno == errno.EADDRNOTAVAIL:
                raise FrameError(f"{where}: {host} is not an address of this machine") from None
            raise FrameError(f"{where}: cannot listen: {exc.strerror or exc}") from None
        self.httpd.daemon_threads = True
        # the socket's own address: its host is text (typeshed allows bytes as an input)
        bound, port_bound = self.httpd.server_address[:2]
        self.address = (bound if isinstance(bound, str) else bytes(bound).decode(), port_bound)
        self.thread = threading.Thread(
            target=self.httpd.serve_forever, kwargs={"poll_interval": 0.2}, daemon=True
        )
        self.thread.start()

    @property
    def url(self) -> str:
        host, port = self.address
        return f"http://{host if ':' not in host else f'[{host}]'}:{port}/"

    def state_json(self) -> bytes:
        return json.dumps(self.state(), separators=(",", ":")).encode()

    def events(self, handler: BaseHTTPRequestHandler) -> None:
        """Stream the state as server-sent events until the client or the server goes."""
        handler.send_response(200)
        handler.send_header("Content-Type", "text/event-stream")
        handler.send_header("Cache-Control", "no-store")
        handler.end_headers()
        last, quiet_since = None, time.monotonic()
        while not self.stopping.is_set():
            data = self.state_json()
            if data != last:
                handler.wfile.write(b"data: " + data + b"\n\n")
                handler.wfile.flush()
                last, quiet_since = data, time.monotonic()
            elif time.monotonic() - quiet_since > KEEPALIVE_S:
                handler.wfile.write(b": keepalive\n\n")
                handler.wfile.flush()
                quiet_since = time.monotonic()
            self.stopping.wait(1.0 / RATE_HZ)

    def close(self) -> None:
        self.stopping.set()
        self.httpd.shutdown()
        self.httpd.server_close()
