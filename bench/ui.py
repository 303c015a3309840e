"""``couture bench ui``: how fast drapes reach the browser, and how long an
edit takes to show.

Runs CoutureUI with the demo garment (default 10k vertices) and a headless
Debian chromium on the 3D view, then:

1. **stream**: a producer offers synthetic predicted drapes at ``--offer-hz``
   for ``--seconds``; counted in the page are the drape frames whose status
   line changed (a MutationObserver on ``#couture-frame``), i.e. updates that
   reached the browser and were applied, per second.
2. **drag**: a scripted mouse drag on the drape; each ``edit`` callback makes
   a fake prediction (a bump at the picked vertex) and shows it. Latency is
   measured per frame from the server receiving the edit (``time.time()`` in
   the edit callback, carried as the frame's tag) to the first
   ``requestAnimationFrame`` in the page after the frame's DOM update, in
   which the new geometry is drawn (same machine, same clock). The pointer →
   server leg is not included; viser throttles drag messages to 20 Hz (50 ms),
   which bounds the edit rate from one pointer.

Both runs repeat for the plain drape (one mesh, vertex updates only) and the
banded strain colour map. Results go to stdout as JSON and to
``ui.json`` in the results folder (``--out``, default bench/results/).
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from bench import ROOT, add_out_arg, write_results
from couture.jsonout import dumps

_OBSERVER_JS = """
() => {
  window.__couture = {frames: []};
  const attach = () => {
    const el = document.getElementById('couture-frame');
    if (!el) { setTimeout(attach, 50); return; }
    const holder = el.parentElement;
    const obs = new MutationObserver(() => {
      const e = document.getElementById('couture-frame');
      if (!e) return;
      const seq = +e.dataset.seq, tag = e.dataset.tag ? JSON.parse(e.dataset.tag) : null, t_dom = Date.now();
      requestAnimationFrame(() => window.__couture.frames.push({seq, tag, t_dom, t_raf: Date.now()}));
    });
    obs.observe(holder.parentElement || holder, {subtree: true, childList: true, attributes: true, characterData: true});
  };
  attach();
}
"""


def _stats(frames: list[dict], t0_ms: float, t1_ms: float) -> dict:
    seqs: dict[int, dict] = {}
    for f in frames:
        if f["tag"] is not None and t0_ms <= f["t_raf"] <= t1_ms + 2000:
            seqs.setdefault(f["seq"], f)
    fr = sorted(seqs.values(), key=lambda f: f["t_raf"])
    lat = np.array([f["t_raf"] - f["tag"]["t"] for f in fr]) if fr else np.zeros(0)
    dur = (t1_ms - t0_ms) / 1000.0
    return {
        "frames_in_browser": len(fr),
        "updates_per_s": round(len(fr) / dur, 2) if dur > 0 else 0.0,
        "latency_ms_median": round(float(np.median(lat)), 1) if lat.size else None,
        "latency_ms_p90": round(float(np.percentile(lat, 90)), 1) if lat.size else None,
    }


def _log(text: str) -> None:
    print(f"[bench ui] {text}", file=sys.stderr, flush=True)


def run(n_vertices: int = 10000, seconds: float = 5.0, offer_hz: float = 120.0, fields=("none", "strain")) -> dict:
    sys.path.insert(0, str(ROOT / "tests"))
    from browser.chromium import browser_page, wait_camera, wait_until  # test helpers: one way to launch chromium

    from couture.bus import free_port
    from couture.ui import CoutureUI, UIConfig
    from couture.ui.demo import demo_sheet, tugged
    from couture.ui.geometry import CameraState

    mesh, pattern = demo_sheet(n_vertices)
    ui = CoutureUI(UIConfig(port=free_port(), draft_locally=False))
    ui.start()
    out: dict = {"n_vertices": mesh.n_vertices, "n_triangles": mesh.n_triangles, "offer_hz": offer_hz, "runs": {}}
    try:
        ui.show_pattern(pattern)
        ui.show_mesh(mesh)
        ui.show_drape(mesh.x0, "fine", "bench")
        x0 = mesh.x0
        with browser_page(1000, 700) as page:
            page.goto(ui.url3d)
            client = wait_camera(ui.server3d, page=page)
            _log("browser connected")
            page.locator("#couture-frame").wait_for(timeout=60_000)
            page.evaluate(_OBSERVER_JS)
            page.wait_for_timeout(1000)
            out["browser"] = page.evaluate("() => navigator.userAgent")
            renderer = page.evaluate("""() => { const c = document.createElement('canvas').getContext('webgl');
                const d = c && c.getExtension('WEBGL_debug_renderer_info');
                return d ? c.getParameter(d.UNMASKED_RENDERER_WEBGL) : 'unknown'; }""")
            out["webgl_renderer"] = renderer
            for field in fields:
                ui.controls.field.value = field  # type: ignore[misc]  # viser has the setter; mypy misses it
                ui.controls.field_chosen()
                page.wait_for_timeout(500)
                # -- stream
                page.evaluate("() => { window.__couture.frames = []; }")
                pushed0 = ui.frames_pushed
                t0 = time.time() * 1000
                k = 0
                while time.time() * 1000 - t0 < seconds * 1000:
                    off = 0.02 * np.array([np.sin(0.2 * k), 0.0, np.cos(0.2 * k)])
                    ui.show_drape(
                        tugged(x0, 0, off),
                        "predicted",
                        "bench",
                        error_estimate=0.0,
                        tag={"t": time.time() * 1000, "k": k},
                    )
                    k += 1
                    time.sleep(1.0 / offer_hz)  # the browser runs on its own; no need to pump playwright here
                t1 = time.time() * 1000
                page.wait_for_timeout(1500)
                frames = page.evaluate("() => window.__couture.frames")
                stream = _stats(frames, t0, t1)
                _log(f"{field} stream: {stream}")
                stream.update(
                    offered=k,
                    pushed_by_server=ui.frames_pushed - pushed0,
                    pushed_per_s=round((ui.frames_pushed - pushed0) / ((t1 - t0) / 1000), 2),
                )
                # -- drag on the drape
                cam = CameraState.from_viser(client.camera)
                front = np.flatnonzero(np.abs(mesh.X[:, 1] - 0.25) < 0.03)
                v = int(front[np.argmax(x0[front, 2])])
                px = cam.to_pixels(x0[v][None])[0]
                edits: list = []

                def on_edit(e, edits: list = edits, v: int = v) -> None:
                    t = time.time() * 1000
                    edits.append(e)
                    dx = np.array([e.d[0], -e.d[1], 0.0]) * 0.001
                    ui.show_drape(
                        tugged(x0, e.pick.vertex if e.pick else v, dx),
                        "predicted",
                        "bench",
                        error_estimate=0.0,
                        tag={"t": t, "phase": e.phase},
                    )

                ui.on_edit = on_edit
                page.evaluate("() => { window.__couture.frames = []; }")
                t0 = time.time() * 1000
                page.mouse.move(*px)
                page.mouse.down()
                steps = 40  # each move waits for the (software-rendered) page: keep the count fixed
                for s in range(steps):
                    a = 2 * np.pi * s / steps
                    page.mouse.move(px[0] + 60 * np.sin(a), px[1] - 40 * (1 - np.cos(a)))
                    page.wait_for_timeout(1000 / 60)
                page.mouse.up()
                t1 = time.time() * 1000
                wait_until(lambda edits=edits: any(e.phase == "release" for e in edits), 20, page)
                page.wait_for_timeout(1500)
                ui.on_edit = None
                frames = page.evaluate("() => window.__couture.frames")
                drag = _stats(frames, t0, t1)
                drag.update(edits=len(edits), edits_per_s=round(len(edits) / ((t1 - t0) / 1000), 2))
                out["runs"][field] = {"stream": stream, "drag": drag}
    finally:
        ui.stop()
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="couture bench ui", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--vertices", type=int, default=10000)
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--offer-hz", type=float, default=120.0)
    ap.add_argument("--fields", default="none,strain", help="colour maps to run, comma-separated")
    add_out_arg(ap)
    a = ap.parse_args(argv)
    res = run(a.vertices, a.seconds, a.offer_hz, tuple(a.fields.split(",")))
    text = dumps(res, indent=2)
    print(text)
    write_results(a.out, "ui", res)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
