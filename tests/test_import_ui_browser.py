"""An imported pattern draped in the real UI (``bench/import_ui.py``):
FreeSewing's penelope skirt with its waistband (cisFemaleAdult34, on L)
through ``couture import`` at 300/400 vertices, the remesher and Newton solver nodes as processes on a
real Zenoh session, the UI and its bus adapter as the ui node runs them, the
page in a headless Debian chromium. The page shows the four pieces (the
backs a 'Cut 2' pair) and the status of a converged fine drape of the imported
design; a back's corner handle dragged in the page commits the edited
design (exactly ``apply_edit`` of the corner's motion: that half and its
twin, the mirror image to 1e-12 m), and a new converged fine drape of it
follows on the page. (``python -m bench.import_ui`` runs the same on
Valentina's Keiko skirt for bench/results/import/ui_keiko.png.) Titan's
trousers, tested here before, start with their crotch seams up to 8 mm
inside the seat of cisMaleAdult38's own body (docs/import.md), and at 400
vertices their fine drape passed through it once (59 mm inside)."""

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

FS = import_ui.ROOT / "tests" / "data" / "imported" / "freesewing"
FINE_TOL = 1e-4
"""the solver's fine-level tolerance (relative residual)"""


def test_imported_skirt_drapes_in_the_ui_and_a_corner_drag_redrapes_both_halves():
    ARTIFACTS.mkdir(exist_ok=True)
    r = import_ui.run(
        FS / "penelope_cisFemaleAdult34.svg",
        FS / "cisFemaleAdult34.json",
        screenshot=ARTIFACTS / "ui_import_penelope.png",
        edited_screenshot=ARTIFACTS / "ui_import_penelope_edited.png",
    )
    print(r)
    assert sorted(r["pieces"]) == ["back_left", "back_right", "front", "waistband"] and r["seams"] == 22
    first, second, drag = r["first"], r["second"], r["drag"]
    for level in ("coarse", "fine"):
        assert first[level]["converged"] and second[level]["converged"], (first, second)
    assert first["fine"]["residual"] < FINE_TOL and second["fine"]["residual"] < FINE_TOL
    assert 300 < first["fine"]["vertices"] < 1000
    # the mannequin is the body the design names (the set's nearest), not the default
    assert r["body"]["shown"] == r["body"]["design"] != "default"
    # the page drew every piece (their fill under most of a grid inside each outline)
    assert min(r["piece_fill"][n] for n in r["pieces"]) > 0.8
    # the drag: the corner went outward, the design committed is apply_edit's, and the
    # 'Cut 2' half moved its twin as its mirror image
    half = drag["element"].split(":")[1]
    assert drag["outward"] and max(abs(c) for c in drag["moved_m"]) > 0.005
    assert drag["apply_edit_gap_m"] < 1e-12
    assert drag["pieces_edited"] == sorted([half, drag["twin"]]) and drag["twin_mirror_gap_m"] < 1e-12
    # a new design, draped again: a later generation whose drape moved
    assert second["fine"]["generation"] > first["fine"]["generation"]
    assert second["drape_moved_m"] is None or second["drape_moved_m"] > 0.002
