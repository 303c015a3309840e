"""``python -m bench.import_ui PATTERN [--body M.json]``: an imported pattern
draped in the real UI, and a piece corner dragged there.

What a user does, with the real parts: ``couture import`` writes the design
(its resolution set small, ``--coarse``/``--fine`` vertices), the remesher and
a solver node (Newton; ``--solver kinetic``: the kinetic one) run as processes on a real Zenoh session (as
``couture up`` starts them; the sensitivity node is left out: nothing here
reads its predictions), the UI (``CoutureUI`` with its bus adapter, as the ui
node runs it, publishing its initial design as the node does for
``--set ui.design=FILE.json``) serves the page to a headless Debian chromium
(tests/browser/chromium.py). Then:

1. the page's pattern view shows the imported pieces (their labels), and its
   status the converged fine drape of that design (level, solver, residual,
   'converged', its generation): a screenshot is taken;
2. a piece's corner handle (the corner farthest from the piece's middle; of
   a 'Cut 2' half where the pattern has one) is
   dragged outward in the pattern view: the UI commits the edited design (a
   'Cut 2' half moves its twin, mirrored), and a new converged fine drape of
   it replaces the first on screen.

``run`` returns the figures (times, iterations, residuals, vertex counts);
``tests/test_import_ui_browser.py`` asserts them, and :func:`main` writes
``ui_<name>.png`` (the first drape) and ``ui_<name>.json`` into
``bench/results/import/`` (``--out``).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import re
import sys
import tempfile
import threading
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from bench import RESULTS_DIR, ROOT, write_results
from schemas.design import Design, Resolution

VALENTINA = ROOT / "tests" / "data" / "imported" / "valentina"
DEFAULT_PATTERN = VALENTINA / "Keiko_skirt_astm.dxf"
DEFAULT_BODY = VALENTINA / "keiko.json"
SOLVER = "newton"
"""the solver node's solver (``couture up --solver NAME``'s node ``solver-NAME``)"""
DRAG_PX = 15.0
"""[page pixels] how far the corner handle is dragged, outward from the piece's middle"""


def _log(text: str) -> None:
    print(f"[bench import_ui] {text}", file=sys.stderr, flush=True)


def import_design(pattern: Path, body: Path | None, out: Path, coarse: int, fine: int) -> Design:
    """``couture import PATTERN [--body BODY] --out OUT``, then the design's
    mesh sizes set to ``coarse``/``fine`` vertices (written back to OUT)."""
    from couture.cli import main as cli
    from couture.pattern.io import load_design, save_design

    argv = ["import", str(pattern), "--out", str(out)] + (["--body", str(body)] if body else [])
    with contextlib.redirect_stdout(io.StringIO()):
        rc = cli(argv)
    if rc != 0:
        raise RuntimeError(f"couture import {pattern} exited {rc}")
    design = load_design(out)
    design.resolution = Resolution(coarse_vertices=coarse, fine_vertices=fine)
    save_design(design, out)
    return design


@dataclass
class Seen:
    """What crosses the bus: fine drapes, and which generation the remesher gave each design id."""

    cond: threading.Condition = field(default_factory=threading.Condition)
    drapes: list = field(default_factory=list)
    generation_of: dict[str, int] = field(default_factory=dict)
    patterns: list = field(default_factory=list)

    def attach(self, bus) -> None:
        def keep(into: list):
            def on(msg) -> None:
                with self.cond:
                    into.append(msg)
                    self.cond.notify_all()

            return on

        def on_mesh(msg) -> None:
            with self.cond:
                if msg.design_id:
                    self.generation_of.setdefault(msg.design_id, msg.generation)
                self.cond.notify_all()

        bus.subscribe("drape/*", keep(self.drapes))
        bus.subscribe("pattern", keep(self.patterns))
        bus.subscribe("mesh/*", on_mesh)

    def wait(self, cond, timeout: float, what: str):
        with self.cond:
            got = self.cond.wait_for(cond, timeout)
        if not got:
            raise TimeoutError(f"{what} not seen in {timeout} s")
        return got

    def final(self, generation: int, level: str):
        """The final drape of ``level`` for ``generation``, once there."""
        return next(
            (m for m in self.drapes if m.level == level and m.final and m.generation == generation),
            None,
        )


@contextlib.contextmanager
def ui_session(design: Design, export_dir: Path, solver: str = SOLVER) -> Iterator[dict[str, Any]]:
    """The remesher and a solver node (``solver``: Newton by default) (processes, a real Zenoh session)
    and an in-process UI on that session with ``design`` as its initial
    design, published once as the ui node does."""
    from couture import supervisor
    from couture.bus import BusConfig, Node, free_port
    from couture.client import Client
    from couture.ui import CoutureUI, UIConfig
    from nodes.ui.main import UIAdapter

    names = ("remesher", f"solver-{solver}")
    nodes = [n for n in supervisor.default_nodes(solvers=[solver], ui=False) if n.name in names]
    cfg = supervisor.SupervisorConfig(
        bus=BusConfig(session=f"i{uuid.uuid4().hex[:8]}", listen=[f"tcp/127.0.0.1:{free_port()}"]), nodes=nodes
    )
    ui = CoutureUI(UIConfig(port=free_port(), export_dir=export_dir), design=design)
    with supervisor.Supervisor(cfg) as sup, Client(bus=sup.child_bus) as client:
        seen = Seen()
        seen.attach(client.bus)
        client.wait_nodes(list(names), timeout=90)
        ui.start()
        try:
            with Node("ui", sup.child_bus, kind="ui", install_signals=False) as node:
                adapter = UIAdapter(node, ui, "ui")
                yield {"ui": ui, "adapter": adapter, "seen": seen, "client": client, "sup": sup}
        finally:
            ui.stop()


def _drag(page, start, end, steps: int = 8) -> None:
    # hover first: a transform handle picks its axis on pointer hover (tests/test_ui_browser.py)
    page.mouse.move(start[0] - 2, start[1])
    page.wait_for_timeout(150)
    page.mouse.move(*start)
    page.wait_for_timeout(250)
    page.mouse.down()
    for k in range(1, steps + 1):
        f = k / steps
        page.mouse.move(start[0] + f * (end[0] - start[0]), start[1] + f * (end[1] - start[1]))
        page.wait_for_timeout(80)  # viser throttles drag messages to 20 Hz
    page.mouse.up()


def _pattern_canvas(page) -> dict:
    """Page-pixel box of the pattern view's canvas (the largest canvas in its iframe)."""
    boxes = [b for c in page.frame_locator("#pattern").locator("canvas").all() if (b := c.bounding_box())]
    return max(boxes, key=lambda b: b["width"] * b["height"])


def _pattern_to_page(page, view2d, p_display: np.ndarray, z: float = 0.0) -> np.ndarray:
    """Page pixels of a display point of the pattern view (its camera looks
    straight down, framed to its canvas by pattern_view.fit_camera)."""
    from couture.ui.pattern_view import CAMERA_FOV, fit_camera

    box = _pattern_canvas(page)
    lo, hi = view2d.bounds()
    (cx, cy, dist), _ = fit_camera(lo, hi, box["width"] / box["height"])
    dist -= z
    f = 0.5 * box["height"] / np.tan(0.5 * CAMERA_FOV)
    return np.array(
        [
            box["x"] + 0.5 * box["width"] + f * (p_display[0] - cx) / dist,
            box["y"] + 0.5 * box["height"] - f * (p_display[1] - cy) / dist,
        ]
    )


DRAWN_TOL = 20
"""[0-255 per channel] a pattern-view pixel farther than this from the view's background is drawn on"""
EDGE_PX = 2.0
"""[page pixels] sample points at least this far inside a piece's outline"""


def _to_outline(P: np.ndarray, q: np.ndarray) -> float:
    """Distance from point q (2,) to the closed polyline P (k, 2)."""
    A, B = P, np.roll(P, -1, axis=0)
    d = B - A
    t = np.clip(((q - A) * d).sum(axis=1) / np.maximum((d * d).sum(axis=1), 1e-300), 0.0, 1.0)
    return float(np.linalg.norm(A + t[:, None] * d - q, axis=1).min())


def _pieces_drawn(page, ui, names: list[str], last: dict[str, float], grid: int = 9) -> dict[str, float] | None:
    """Per piece, the share of points on a grid inside its outline (as the
    pattern view places it) whose page pixel is drawn on (the panel's fill,
    lit, differs from the background, read below every piece); None until
    every piece has more than 80 % of them and the background point none
    (the piece labels are WebGL text, not in the page's DOM). ``last`` gets
    the newest shares."""
    from PIL import Image

    from couture.ui.pattern_view import _inside

    v2, pat = ui.view2d, ui.pattern
    if pat is None or any(n not in {p.name for p in pat.panels} for n in names):
        return None
    box = _pattern_canvas(page)
    clip = {k: float(box[k]) for k in ("x", "y", "width", "height")}
    shot = np.asarray(Image.open(io.BytesIO(page.screenshot(clip=clip))).convert("RGB")).astype(int)

    def rgb(q: np.ndarray) -> np.ndarray:
        x, y = (_pattern_to_page(page, v2, q, z=-0.002) - [clip["x"], clip["y"]]).round().astype(int)
        return shot[min(max(y, 0), shot.shape[0] - 1), min(max(x, 0), shot.shape[1] - 1)]

    lo, hi = v2.bounds()
    lo, hi = np.asarray(lo, float)[:2], np.asarray(hi, float)[:2]
    background = rgb(np.array([0.5 * (lo[0] + hi[0]), lo[1] - 0.05 * (hi[1] - lo[1])]))
    # page pixels per display unit: a point nearer a piece's outline than EDGE_PX is not sampled
    # (a thin piece, a binding a few pixels high, would read its anti-aliased edge)
    px = float(
        np.linalg.norm(_pattern_to_page(page, v2, np.array([1.0, 0.0])) - _pattern_to_page(page, v2, np.zeros(2)))
    )
    share = {}
    for n in names:
        P = v2.display(n, pat.panel(n).outline)
        a, b = P.min(axis=0), P.max(axis=0)
        g = np.linspace(0.1, 0.9, grid)
        pts = [a + (b - a) * np.array([u, v]) for u in g for v in g]
        pts = [q for q in pts if _inside(P, q) and _to_outline(P, q) * px >= EDGE_PX]
        drawn = [bool(np.abs(rgb(q) - background).max() > DRAWN_TOL) for q in pts]
        share[n] = float(np.mean(drawn)) if drawn else 0.0
    last.update(share, background=float(background.mean()))
    _log(f"pieces drawn: {last}")
    return share if min(share.values()) > 0.8 and background.min() > 200 else None


def _drape_figures(m) -> dict[str, Any]:
    return {
        "iterations": int(m.iterations),
        "residual": float(m.residual),
        "converged": bool(m.converged),
        "solve_s": round(float(m.wall_time_s), 2),
        "vertices": int(np.asarray(m.x.numpy()).shape[0]),
        "generation": int(m.generation),
    }


def _converged_fine(sess: dict[str, Any], design_id: str, timeout: float, what: str):
    """(coarse, fine) final drapes of the design published as ``design_id``,
    once the fine one is converged and on the UI's screen."""
    seen, ui = sess["seen"], sess["ui"]
    gen = seen.wait(lambda: seen.generation_of.get(design_id), timeout, f"the remesher's number for {what}")
    fine = seen.wait(lambda: seen.final(gen, "fine"), timeout, f"the final fine drape of {what}")
    if not fine.converged:
        raise AssertionError(f"the fine drape of {what} did not converge: {fine.diagnosis} (residual {fine.residual})")
    t0 = time.monotonic()
    while not (
        (f := ui.on_screen) is not None and f.level == "fine" and f.final and f.generation == gen and f.converged
    ):
        if time.monotonic() - t0 > 30:
            raise TimeoutError(f"the UI did not put the fine drape of {what} on screen in 30 s: {f}")
        time.sleep(0.1)
    return seen.final(gen, "coarse"), fine


def run(
    pattern: Path = DEFAULT_PATTERN,
    body: Path | None = DEFAULT_BODY,
    *,
    coarse: int = 300,
    fine: int = 400,
    screenshot: Path | None = None,
    edited_screenshot: Path | None = None,
    timeout: float = 120.0,
    solver: str = SOLVER,
) -> dict[str, Any]:
    """Import, drape in the UI, drag a corner, drape again (see the module
    doc); returns the figures. Raises when a step is not seen in the page."""
    sys.path.insert(0, str(ROOT / "tests"))
    from browser.chromium import browser_page, wait_camera, wait_until  # one way to launch chromium

    from couture.pattern import apply_edit

    out: dict[str, Any] = {
        "pattern": str(Path(pattern).relative_to(ROOT)) if Path(pattern).is_absolute() else str(pattern),
        "solver": solver,
    }
    t_all = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="couture-import-ui-") as tmp:
        t = time.monotonic()
        design = import_design(Path(pattern), body, Path(tmp) / "design.json", coarse, fine)
        out["import_s"] = round(time.monotonic() - t, 2)
        out["pieces"] = [pc.name for pc in design.pieces]
        out["seams"] = sum(st.kind == "seam" for st in design.strokes)
        t = time.monotonic()
        with ui_session(design, Path(tmp) / "exports", solver) as sess:
            ui, adapter, seen = sess["ui"], sess["adapter"], sess["seen"]
            out["nodes_up_s"] = round(time.monotonic() - t, 2)
            t = time.monotonic()
            adapter.publish_design(ui.design)  # as the ui node does with its initial design
            first_id = seen.wait(
                lambda: next((p.design_id for p in seen.patterns if p.source == "ui"), None), 30, "the UI's design"
            )
            coarse1, fine1 = _converged_fine(sess, first_id, timeout, "the imported design")
            out["first"] = {
                "coarse": _drape_figures(coarse1),
                "fine": _drape_figures(fine1),
                "publish_to_screen_s": round(time.monotonic() - t, 2),
            }
            _log(f"first drape: {out['first']}")
            with browser_page(1400, 800) as page:
                t = time.monotonic()
                page.goto(ui.page_url)
                wait_camera(ui.server3d, page=page)
                wait_camera(ui.server2d, page=page)
                _log(f"page connected in {time.monotonic() - t:.1f} s")
                f3 = page.frame_locator("#view3d")
                # the page's own status says what is on screen (its table, not the frame marker: see
                # tests/test_adjust_browser.py), and the pattern view draws every imported piece
                gen1 = fine1.generation
                f3.get_by_text(
                    re.compile(rf"fine solve by solver-{solver}.*converged, generation {gen1}\b")
                ).first.wait_for(timeout=90_000)
                _log(f"status in {time.monotonic() - t:.1f} s")
                out["body"] = {"design": design.body.name, "shown": ui.view3d.body_name}
                last: dict[str, float] = {}
                try:
                    out["piece_fill"] = wait_until(lambda: _pieces_drawn(page, ui, out["pieces"], last), 60, page)
                except TimeoutError:
                    raise TimeoutError(f"the pattern view did not draw every piece: fill share {last}") from None
                _log(f"status and pieces in {time.monotonic() - t:.1f} s")
                out["page_shows_first_s"] = round(time.monotonic() - t, 2)
                page.wait_for_timeout(1500)  # software WebGL: let it draw the drape
                if screenshot is not None:
                    Path(screenshot).parent.mkdir(parents=True, exist_ok=True)
                    page.screenshot(path=str(screenshot))

                # drag the corner handle farthest from its piece's middle outward
                v2 = ui.view2d
                wait_until(lambda: ui.handles_for is not None and len(v2.handles) > 0, 30, page)
                pat = ui.pattern
                piece_names = set(out["pieces"])
                halves = {pc.name for pc in design.pieces if pc.mirror_of}  # a 'Cut 2' half, where there is one
                piece_names = (piece_names & halves) or piece_names
                i, h = max(
                    ((i, h) for i, h in enumerate(v2.handles) if h.kind == "pt" and h.panel in piece_names),
                    key=lambda ih: float(
                        np.linalg.norm(
                            pat.panel(ih[1].panel).outline[ih[1].vertex] - pat.panel(ih[1].panel).outline.mean(axis=0)
                        )
                    ),
                )
                P = pat.panel(h.panel).outline
                outward = P[h.vertex] - P.mean(axis=0)
                out_px = np.array([outward[0], -outward[1]]) / np.linalg.norm(outward)  # on screen, +y is up
                before = next(pc for pc in design.pieces if pc.name == h.panel)
                n0 = len(seen.patterns)
                tries = []
                t = time.monotonic()
                for _ in range(4):  # a drag that starts while the page still draws may be dropped
                    start = _pattern_to_page(page, v2, v2.handle_positions()[i, :2], z=0.003)
                    _drag(page, start, start + DRAG_PX * out_px)
                    try:
                        wait_until(
                            lambda: any(p.source == "ui" for p in seen.patterns[n0:]),
                            30,
                            page,
                        )
                    except TimeoutError:
                        tries.append([round(float(c)) for c in start])
                        page.wait_for_timeout(1000)
                        continue
                    break
                else:
                    raise TimeoutError(f"no design from 4 drags of the corner handle {h.element} (page pixels {tries})")
                edited_msg = next(p for p in reversed(seen.patterns[n0:]) if p.source == "ui")
                after = next(pc for pc in edited_msg.design.pieces if pc.name == h.panel)
                moved = np.asarray(after.outline)[h.vertex] - np.asarray(before.outline)[h.vertex]
                # the committed design is apply_edit of the element by the corner's motion
                expect = apply_edit(design, h.element, moved)
                out["drag"] = {
                    "element": h.element,
                    "moved_m": [round(float(c), 5) for c in moved],
                    "outward": bool(moved @ outward > 0),
                    "apply_edit_gap_m": float(
                        max(
                            np.abs(np.asarray(a.outline) - np.asarray(b.outline)).max()
                            for a, b in zip(expect.pieces, edited_msg.design.pieces, strict=True)
                        )
                    ),
                    "pieces_edited": sorted(
                        a.name
                        for a, b in zip(design.pieces, edited_msg.design.pieces, strict=True)
                        if a.outline != b.outline
                    ),
                }
                twin = next((pc for pc in edited_msg.design.pieces if pc.mirror_of == h.panel), None)
                if twin is not None:  # a 'Cut 2' half: its twin is the mirror image of the edited half
                    from couture.pattern.pieces import mirror_outline

                    out["drag"]["twin"] = twin.name
                    out["drag"]["twin_mirror_gap_m"] = float(
                        np.abs(mirror_outline(after, twin) - np.asarray(twin.outline)).max()
                    )
                _log(f"drag: {out['drag']}")
                coarse2, fine2 = _converged_fine(sess, edited_msg.design_id, timeout, "the edited design")
                gen2 = fine2.generation
                f3.get_by_text(
                    re.compile(rf"fine solve by solver-{solver}.*converged, generation {gen2}\b")
                ).first.wait_for(timeout=60_000)
                x1, x2 = np.asarray(fine1.x.numpy()), np.asarray(fine2.x.numpy())
                out["second"] = {
                    "coarse": _drape_figures(coarse2),
                    "fine": _drape_figures(fine2),
                    "release_to_page_s": round(time.monotonic() - t, 2),
                    "drape_moved_m": round(float(np.abs(x2 - x1).max()), 4) if x1.shape == x2.shape else None,
                }
                _log(f"second drape: {out['second']}")
                if edited_screenshot is not None:
                    page.wait_for_timeout(1500)
                    page.screenshot(path=str(edited_screenshot))
    out["total_s"] = round(time.monotonic() - t_all, 2)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m bench.import_ui", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("pattern", nargs="?", type=Path, default=DEFAULT_PATTERN, help="DXF or SVG (default: %(default)s)")
    ap.add_argument("--body", type=Path, default=None, help="measurement set (with the default pattern: keiko.json)")
    ap.add_argument("--name", default=None, help="picture name: ui_<name>.png (default: the pattern's stem)")
    ap.add_argument("--coarse", type=int, default=300)
    ap.add_argument("--fine", type=int, default=400)
    ap.add_argument("--timeout", type=float, default=120.0, help="[s] to wait for each converged fine drape")
    ap.add_argument("--solver", default=SOLVER, help="the solver node's solver (default: %(default)s)")
    ap.add_argument(
        "--out",
        type=Path,
        default=RESULTS_DIR / "import",
        metavar="DIR",
        help="results folder: writes ui_<name>.json and ui_<name>.png there (default: %(default)s)",
    )
    a = ap.parse_args(argv)
    body = a.body if a.body is not None else (DEFAULT_BODY if a.pattern == DEFAULT_PATTERN else None)
    name = a.name or a.pattern.stem
    res = run(
        a.pattern,
        body,
        coarse=a.coarse,
        fine=a.fine,
        screenshot=a.out / f"ui_{name}.png",
        timeout=a.timeout,
        solver=a.solver,
    )
    res["picture"] = f"ui_{name}.png"
    print(write_results(a.out, f"ui_{name}", res).read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
