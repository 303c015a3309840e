"""An imported design in the UI (headless viser): it adopts the design, shows
the pieces, and the seam tool sews two of their segments into a design the
pattern model drafts; the sloper's sliders go (a design of pieces has no options)."""

from __future__ import annotations

from pathlib import Path

from couture.bus.ports import free_port
from couture.pattern import draft
from couture.pattern.imported import read_pattern
from couture.pattern.sewing import build_design
from couture.ui.app import CoutureUI, UIConfig

VAL = Path(__file__).parent / "data" / "imported" / "valentina"


def test_ui_shows_and_sews_imported_pieces(tmp_path):
    design, rep = build_design(read_pattern(VAL / "TShirt_test_astm.dxf"))
    ui = CoutureUI(UIConfig(port=free_port(), export_dir=tmp_path, show_body=False, draft_locally=False))
    ui.start()
    try:
        ui.set_design(design)
        pat = draft(design)
        ui.show_pattern(pat)
        assert ui.design is design
        assert ui.controls.params == {}  # no sloper options: the last sloper's sliders are gone
        got = []
        ui.on_design_changed = got.append
        a, b = pat.panels[1], pat.panels[2]
        free = {(p, g) for p, g, _ in rep.free}
        sa = next(s for s in a.segments if (a.name, s.name) in free)
        sb = next(s for s in b.segments if (b.name, s.name) in free)
        ui.tools.arm("seam")
        ui.tools.click(ui.view2d.display(a.name, a.outline[(sa.start + 1) % len(a.outline)]), a.name)
        ui.tools.click(ui.view2d.display(b.name, b.outline[(sb.start + 1) % len(b.outline)]), b.name)
        seam = got[-1].strokes[-1]
        assert seam.kind == "seam"
        assert {
            (seam.params["a_panel"], seam.params["a_segment"]),
            (seam.params["b_panel"], seam.params["b_segment"]),
        } == {
            (a.name, sa.name),
            (b.name, sb.name),
        }
        assert len(draft(got[-1]).seams) == len(pat.seams) + 1
        assert got[-1].pieces == design.pieces
    finally:
        ui.stop()
