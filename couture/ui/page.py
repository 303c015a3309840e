"""The one page a designer opens: the 3D view and the pattern view side by
side, each an iframe onto its own viser server (viser has one scene per
server). Served by a stdlib HTTP server in a thread, on the same host."""

from __future__ import annotations

import http.server
import threading

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


class PageServer:
    """Serves the combined page at ``http://host:port/``."""

    def __init__(self, host: str, port: int, port3d: int, port2d: int):
        body = PAGE.format(port3d=port3d, port2d=port2d).encode()

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self) -> None:  # noqa: N802 (stdlib name)
                if self.path not in ("/", "/index.html"):
                    self.send_error(404)
                    return
                self.send_response(200)
                self.send_header("Content-Type", "text/html; charset=utf-8")
                self.send_header("Content-Length", str(len(body)))
                self.send_header("Cache-Control", "no-store")
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *args) -> None:
                pass

        self.httpd = http.server.ThreadingHTTPServer((host, port), Handler)
        self.httpd.daemon_threads = True
        # an AF_INET server's address is (str, int); typeshed allows bytes for the host
        self.host, self.port = str(self.httpd.server_address[0]), self.httpd.server_address[1]
        self._thread = threading.Thread(target=self.httpd.serve_forever, name="couture-page", daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}/"

    def stop(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()
        self._thread.join(timeout=2.0)
