"""The one page a designer opens: the 3D view and the pattern view side by
side, each an iframe onto its own viser server (viser has one scene per
server). Served by a stdlib HTTP server in a thread, on the same host.

The page's port is bound first; a taken port is either an error naming it
or, with ``fallback``, the next free one (port + 3, + 6, ..., then any):
the URL the server reports (:attr:`PageServer.url`) is always its own."""

from __future__ import annotations

import errno
import http.server
import logging
import threading

log = logging.getLogger("couture.ui")

FALLBACK_STEPS = 10
"""ports tried above a taken one (in steps of 3: page, 3D view, pattern view) before any free port"""

PAGE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>couture</title>
<style>
 html, body {{ margin: 0; height: 100%; font-family: sans-serif; }}
 #bar {{ height: 28px; line-height: 28px; padding: 0 10px; background: #2b2b2b; color: #eee; font-size: 13px; }}
 #views {{ display: flex; height: calc(100% - 28px); }}
 iframe {{ border: 0; height: 100%; }}
 /* the mannequin is taller than wide, the laid-out pattern wider than tall */
 #view3d {{ flex: 1 1 55%; }}
 #pattern {{ flex: 1 1 45%; }}
 #pattern {{ border-left: 2px solid #888; }}
</style></head>
<body>
<div id="bar">couture · left: drape on the mannequin (drag the cloth to tug) · right: sewing pattern (drag the handles)</div>
<div id="views">
 <iframe id="view3d" title="3D drape"></iframe>
 <iframe id="pattern" title="pattern"></iframe>
</div>
<script>
 // same host the page came from, so the page works whatever name reached it
 const h = location.hostname;
 document.getElementById("view3d").src = "http://" + h + ":{port3d}/";
 document.getElementById("pattern").src = "http://" + h + ":{port2d}/";
</script>
</body></html>
"""


class PortInUse(OSError):
    """The page's port is taken and no other was to be chosen."""


class PageServer:
    """Serves the combined page at ``http://host:port/``. The views' ports
    are given now or later (:meth:`set_views`; until then the page answers 503)."""

    def __init__(
        self, host: str, port: int, port3d: int | None = None, port2d: int | None = None, *, fallback: bool = False
    ):
        self.body: bytes | None = None
        if port3d is not None and port2d is not None:
            self.set_views(port3d, port2d)
        server = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self) -> None:  # noqa: N802 (stdlib name)
                if self.path not in ("/", "/index.html"):
                    self.send_error(404)
                    return
                body = server.body
                if body is None:
                    self.send_error(503, "the views are starting")
                    return
                self.send_response(200)
                self.send_header("Content-Type", "text/html; charset=utf-8")
                self.send_header("Content-Length", str(len(body)))
                self.send_header("Cache-Control", "no-store")
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *args) -> None:
                pass

        self.requested_port = port
        self.httpd = _bind(host, port, Handler, fallback)
        self.httpd.daemon_threads = True
        # an AF_INET server's address is (str, int); typeshed allows bytes for the host
        self.host, self.port = str(self.httpd.server_address[0]), self.httpd.server_address[1]
        self._thread = threading.Thread(target=self.httpd.serve_forever, name="couture-page", daemon=True)
        self._thread.start()

    def set_views(self, port3d: int, port2d: int) -> None:
        """The ports of the 3D and pattern views' servers (same host)."""
        self.body = PAGE.format(port3d=port3d, port2d=port2d).encode()

    @property
    def url(self) -> str:
        """Where this server serves the page (its own port, whatever was asked)."""
        return f"http://{self.host}:{self.port}/"

    def stop(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()
        self._thread.join(timeout=2.0)


def _bind(host: str, port: int, handler: type, fallback: bool) -> http.server.ThreadingHTTPServer:
    """An HTTP server on ``port``; when it is taken, PortInUse, or with
    ``fallback`` the first free of port + 3, port + 6, ... and then any free port."""
    candidates = [port] + ([port + 3 * k for k in range(1, FALLBACK_STEPS + 1)] + [0] if fallback and port else [])
    for p in candidates:
        try:
            httpd = http.server.ThreadingHTTPServer((host, p), handler)
        except OSError as e:
            if e.errno != errno.EADDRINUSE:
                raise
            if not fallback:
                raise PortInUse(
                    errno.EADDRINUSE,
                    f"port {port} on {host} is already in use (another couture UI or session?): choose another port",
                ) from None
            continue
        if p != port:
            log.warning("port %d on %s is in use (another couture UI?): serving the page on port %d", port, host, p)
        return httpd
    raise PortInUse(errno.EADDRINUSE, f"no free port for the page near {port} on {host}")
