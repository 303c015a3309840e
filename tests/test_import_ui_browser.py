"""An imported pattern draped in the real UI (``bench/import_ui.py``): Valentina's
Keiko skirt (ASTM DXF, keiko.json's measurements) through ``couture import``
at 300/400 vertices, the remesher and Newton solver nodes as processes on a
real Zenoh session, the UI and its bus adapter as the ui node runs them, the
page in a headless Debian chromium. The page shows both pieces and the status
of a converged fine drape of the imported design; a piece's corner handle
dragged in the page commits the edited design (exactly ``apply_edit`` of the
corner's motion, that piece alone), and a new converged fine drape of it
follows on the page."""

from __future__ import annotations

import os

import pytest
from browser.chromium import ARTIFACTS, available

from bench import import_ui

pytestmark = [
    pytest.mark.browser,
    pytest.mark.slow,
    pytest.mark.timeout(420),
    pytest.mark.skipif(
        not available() and not os.environ.get("CI"),
        reason="needs /usr/bin/chromium + playwright (scripts/setup.sh --test installs them; never skipped in CI)",
    ),
]

FINE_TOL = 1e-4
"""the solver's fine-level tolerance (relative residual)"""


def test_imported_skirt_drapes_in_the_ui_and_a_corner_drag_redrapes_it():
    ARTIFACTS.mkdir(exist_ok=True)
    r = import_ui.run(
        screenshot=ARTIFACTS / "ui_import_keiko.png", edited_screenshot=ARTIFACTS / "ui_import_keiko_edited.png"
    )
    print(r)
    assert r["pieces"] == ["piece1", "piece2"] and r["seams"] == 2
    first, second, drag = r["first"], r["second"], r["drag"]
    for level in ("coarse", "fine"):
        assert first[level]["converged"] and second[level]["converged"], (first, second)
    assert first["fine"]["residual"] < FINE_TOL and second["fine"]["residual"] < FINE_TOL
    assert 300 < first["fine"]["vertices"] < 1000
    # the mannequin is the body the design names (keiko.json's nearest, XS), not the default
    assert r["body"] == {"design": "XS", "shown": "XS"}
    # the page drew both pieces (their fill under most of a grid inside each outline)
    assert min(r["piece_fill"][n] for n in r["pieces"]) > 0.8
    # the drag: the corner went outward, the design committed is apply_edit's, one piece changed
    assert drag["outward"] and max(abs(c) for c in drag["moved_m"]) > 0.005
    assert drag["apply_edit_gap_m"] < 1e-12 and drag["pieces_edited"] == [drag["element"].split(":")[1]]
    # a new design, draped again: a later generation whose drape moved
    assert second["fine"]["generation"] > first["fine"]["generation"]
    assert second["drape_moved_m"] is None or second["drape_moved_m"] > 0.002
