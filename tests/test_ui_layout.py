"""The layout a designer sees, with the dress (couture/pattern/examples/dress.json),
in a real headless chromium (Debian's; see tests/browser/chromium.py): the
mannequin fills the 3D view, the tool panel covers no pattern piece, and
handle names show only for the selected handle.

Geometry is read from the browser's own camera (as viser reports it) and the
page's DOM rectangles; screenshots go to test-artifacts/ for a look.
"""

from __future__ import annotations

import os

import numpy as np
import pytest
from browser.chromium import ARTIFACTS, available, browser_page, stable_camera, wait_camera, wait_until

pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(
        not available() and not os.environ.get("CI"),
        reason="needs /usr/bin/chromium + playwright (scripts/setup.sh --test installs them; never skipped in CI)",
    ),
]

DRESS = "couture/pattern/examples/dress.json"


@pytest.fixture(scope="module")
def dress():
    from pathlib import Path

    from couture.bus import free_port
    from couture.client import load_design
    from couture.ui import CoutureUI, UIConfig

    ARTIFACTS.mkdir(exist_ok=True)
    design = load_design(Path(__file__).resolve().parents[1] / DRESS)
    ui = CoutureUI(UIConfig(port=free_port(), export_dir=ARTIFACTS / "exports"), design=design)
    ui.start()
    try:
        with browser_page(1400, 800) as page:
            page.goto(ui.page_url)
            c3 = wait_camera(ui.server3d, page=page)
            c2 = wait_camera(ui.server2d, page=page)
            wait_until(lambda: ui.handles_for is design and ui.view2d.handles, 120, page)
            yield {"ui": ui, "page": page, "c3": stable_camera(c3, page) and c3, "c2": stable_camera(c2, page) and c2}
    finally:
        ui.stop()


def _canvas_box(page, iframe: str) -> dict:
    """Page-pixel box of a view's 3D canvas (the largest canvas in its iframe)."""
    boxes = [b for c in page.frame_locator(iframe).locator("canvas").all() if (b := c.bounding_box())]
    return max(boxes, key=lambda b: b["width"] * b["height"])


def _to_page(cam, box: dict, points: np.ndarray) -> np.ndarray:
    """World points [m] -> page pixels, through the browser's camera and the canvas's place on the page."""
    uv = cam.project(points)
    return uv * np.array([box["width"], box["height"]]) + np.array([box["x"], box["y"]])


def test_mannequin_fills_the_3d_view(dress):
    from couture.ui.geometry import CameraState

    ui, page = dress["ui"], dress["page"]
    cam = CameraState.from_viser(stable_camera(dress["c3"], page))
    frame, box = page.locator("#view3d").bounding_box(), _canvas_box(page, "#view3d")
    assert box["height"] >= 0.95 * frame["height"]  # the canvas has the frame's full height
    px = _to_page(cam, box, ui.view3d.body_vertices)
    lo, hi = px.min(axis=0), px.max(axis=0)
    page.screenshot(path=str(ARTIFACTS / "ui_layout_dress.png"))
    # all of the mannequin is in the canvas ...
    assert lo[0] >= box["x"] and hi[0] <= box["x"] + box["width"], (lo, hi, box)
    assert lo[1] >= box["y"] and hi[1] <= box["y"] + box["height"], (lo, hi, box)
    # ... and spans most of its height (or, on a narrow canvas, of its width: the arms)
    fill = max((hi[1] - lo[1]) / box["height"], (hi[0] - lo[0]) / box["width"])
    assert fill > 0.85, f"the mannequin spans {fill:.0%} of the 3D view"
    assert (hi[1] - lo[1]) / box["height"] > 0.75


def test_tool_panel_covers_no_pattern_piece(dress):
    from couture.ui.geometry import CameraState

    ui, page = dress["ui"], dress["page"]
    cam = CameraState.from_viser(stable_camera(dress["c2"], page))
    box = _canvas_box(page, "#pattern")
    frame = page.frame_locator("#pattern")
    controls = [
        frame.get_by_role("button", name=n)
        for n in ("Add a curve point", "Draw a dart", "Sew two segments", "Mark symmetry", "Cancel tool")
    ]
    controls.append(frame.get_by_text("show all handle names"))
    rects = [c.bounding_box() for c in controls]
    panel_lo = np.array([min(r["x"] for r in rects), min(r["y"] for r in rects)])
    panel_hi = np.array([max(r["x"] + r["width"] for r in rects), max(r["y"] + r["height"] for r in rects)])
    view = ui.view2d
    assert len(view.pattern.panels) == 2
    for p in view.pattern.panels:
        pts = view.display(p.name, p.outline)
        px = _to_page(cam, box, np.column_stack([pts, np.zeros(len(pts))]))
        lo, hi = px.min(axis=0), px.max(axis=0)
        overlap = np.all(lo < panel_hi) and np.all(panel_lo < hi)
        assert not overlap, f"the tool panel {panel_lo}..{panel_hi} covers piece {p.name} {lo}..{hi}"
        inside = np.all(lo >= [box["x"], box["y"]]) and np.all(
            hi <= [box["x"] + box["width"], box["y"] + box["height"]]
        )
        assert inside, f"piece {p.name} {lo}..{hi} is not all in the pattern canvas {box}"


def test_handle_names_show_on_selection_only(dress):
    from couture.ui.geometry import CameraState

    ui, page = dress["ui"], dress["page"]
    view = ui.view2d
    assert len(view.handles) > 10 and view.visible_labels() == []
    page.screenshot(path=str(ARTIFACTS / "ui_layout_labels_hidden.png"))
    cam = CameraState.from_viser(stable_camera(dress["c2"], page))
    box = _canvas_box(page, "#pattern")
    pos = view.handle_positions()
    # the handle farthest from the others (a click there can only mean it)
    gaps = np.linalg.norm(pos[:, None, :2] - pos[None, :, :2], axis=-1) + np.eye(len(pos)) * 1e9
    i = int(np.argmax(gaps.min(axis=1)))
    page.mouse.click(*_to_page(cam, box, pos[i][None])[0])
    wait_until(lambda: view.visible_labels() == [view.handles[i].label], 30, page)
    page.wait_for_timeout(1000)
    page.screenshot(path=str(ARTIFACTS / "ui_layout_label_selected.png"))
    # a click on empty cloth clears the selection
    empty = np.array([box["x"] + 0.5 * box["width"], box["y"] + 0.95 * box["height"]])
    page.mouse.click(*empty)
    wait_until(lambda: view.visible_labels() == [], 30, page)
