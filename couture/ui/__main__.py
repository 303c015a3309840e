"""Standalone UI with a demo garment, no bus: ``python -m couture.ui [--port 8080]``.

Drags and slider changes are printed; a drag on the drape shows a fake
prediction (a bump following the pointer) so the page can be tried alone.
"""

from __future__ import annotations

import argparse
import signal
import threading

import numpy as np

from couture.ui import CoutureUI, UIConfig
from couture.ui.demo import demo_sheet, tugged
from couture.ui.gestures import Edit


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m couture.ui", description=__doc__)
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument(
        "--port", type=int, default=8080, help="the page; the 3D view is port + 1, the pattern view port + 2"
    )
    ap.add_argument("--vertices", type=int, default=3000, help="demo sheet size")
    args = ap.parse_args(argv)

    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    ui = CoutureUI(UIConfig(host=args.host, port=args.port))
    url = ui.start()
    try:
        mesh, pattern = demo_sheet(args.vertices)
        ui.show_pattern(pattern)
        ui.show_mesh(mesh)
        ui.show_drape(mesh.x0, "fine", "demo", residual=float("nan"))
        x = mesh.x0

        def on_edit(edit: Edit) -> None:
            print("edit", edit.phase, edit.element, np.round(edit.d, 4).tolist(), flush=True)
            if edit.pick is not None:
                dx = np.array([edit.d[0], -edit.d[1], 0.0]) * 0.0015  # px -> m, screen y down
                ui.show_drape(tugged(x, edit.pick.vertex, dx), "predicted", "demo", error_estimate=0.0)

        ui.on_edit = on_edit
        ui.on_design_changed = lambda d: print("design", d.sloper.kind, d.sloper.params, flush=True)
        print(f"couture UI: {url}  (3D {ui.url3d}, pattern {ui.url2d})", flush=True)
        stop.wait()
    finally:
        ui.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
