"""The HTTP endpoint: ``/health``, ``/tracks``, ``/biases`` (JSON) and ``/metrics`` (Prometheus).

Served from a thread of its own; it reads only the views the tracker loop replaces whole
(``Service.view``, ``Service.tracks_json``, ``Service.biases_json``), never the live manager.
"""

from __future__ import annotations

import json
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

from prometheus_client import CONTENT_TYPE_LATEST, generate_latest

from radartracker.errors import ConfigurationError


def serve_http(service, host: str, port: int) -> ThreadingHTTPServer:
    """Start the HTTP server for ``service`` in a daemon thread; ``shutdown()`` stops it."""

    class Handler(BaseHTTPRequestHandler):
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
        server = ThreadingHTTPServer((host, port), Handler)
    except OSError as exc:
        raise ConfigurationError(f"cannot serve HTTP on {host}:{port}: {exc}") from None
    server.daemon_threads = True
    threading.Thread(target=server.serve_forever, name="radartracker-http", daemon=True).start()
    return server
