"""The HTTP endpoint: ``/health``, ``/tracks``, ``/biases`` (JSON) and ``/metrics`` (Prometheus).

Served from a thread of its own; it reads only the views the tracker loop replaces whole
(``Service.view``, ``Service.tracks_json``, ``Service.biases_json``), never the live manager.

Bounded whatever the clients do (issue 33: 3 000 half-sent requests made 3 000 threads and 929
``BrokenPipeError`` tracebacks): requests run on :data:`WORKERS` threads, each connection times out
after :data:`TIMEOUT_S` without data, beyond :data:`MAX_PENDING` waiting connections a new one is
closed at once, and a client that goes away is counted (``errors``), not logged with a traceback.
"""

from __future__ import annotations

import json
import threading
from concurrent.futures import ThreadPoolExecutor
from http.server import BaseHTTPRequestHandler, HTTPServer

from prometheus_client import CONTENT_TYPE_LATEST, generate_latest

from radartracker.errors import ConfigurationError


WORKERS = 4
TIMEOUT_S = 5.0
MAX_PENDING = 64


class PooledHTTPServer(HTTPServer):
    """An HTTP server whose requests run on a few pooled threads (module docstring)."""

    request_queue_size = 128  # the listen backlog: connections the kernel holds until accepted

    def __init__(self, address: tuple[str, int], handler: type) -> None:
        super().__init__(address, handler)
        self.pool = ThreadPoolExecutor(WORKERS, thread_name_prefix="radartracker-http")
        self.pending = threading.BoundedSemaphore(MAX_PENDING)
        self.refused = self.errors = 0

    def process_request(self, request, client_address) -> None:
        if not self.pending.acquire(blocking=False):  # too many waiting: this one is closed now
            self.refused += 1
            self.shutdown_request(request)
            return
        self.pool.submit(self._work, request, client_address)

    def _work(self, request, client_address) -> None:
        try:
            self.finish_request(request, client_address)
        except Exception:  # noqa: BLE001 (a client that timed out or went away)
            self.errors += 1
        finally:
            self.shutdown_request(request)
            self.pending.release()

    def server_close(self) -> None:
        super().server_close()
        self.pool.shutdown(wait=False, cancel_futures=True)


def serve_http(service, host: str, port: int) -> PooledHTTPServer:
    """Start the HTTP server for ``service`` in a daemon thread; ``shutdown()`` stops it."""

    class Handler(BaseHTTPRequestHandler):
        timeout = TIMEOUT_S  # a connection silent this long is closed

        def do_GET(self) -> None:  # noqa: N802 (http.server's name)
            path = self.path.split("?", 1)[0]
            if path == "/metrics":
                self._send(200, generate_latest(service.metrics.registry), CONTENT_TYPE_LATEST)
            elif path in ("/health", "/tracks", "/biases"):
                body = {"/health": service.health, "/tracks": lambda: service.tracks_json,
                        "/biases": lambda: service.biases_json}[path]()
                self._send(200, json.dumps(body, default=str).encode(), "application/json")
            else:
                self._send(404, b'{"error": "not found: /health, /tracks, /biases, /metrics"}', "application/json")

        def _send(self, code: int, body: bytes, ctype: str) -> None:
            self.send_response(code)
            self.send_header("Content-Type", ctype)
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args) -> None:  # no line per request on stderr
            pass

    try:
        server = PooledHTTPServer((host, port), Handler)
    except OSError as exc:
        raise ConfigurationError(f"cannot serve HTTP on {host}:{port}: {exc}") from None
    threading.Thread(target=server.serve_forever, name="radartracker-http", daemon=True).start()
    return server
