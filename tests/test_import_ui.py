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
        assert ui.controls.sloper.value == "none" and ui.controls.sloper.options[0] == "none"  # not 'skirt'
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


def test_ui_seams_folder_shows_confidence_and_drops_or_confirms_a_suggestion(tmp_path):
    """The pattern view's Seams folder lists an imported design's seams with
    the importer's confidence, least sure first; Drop removes the chosen
    seam (its segments become free: one seam fewer drafted), Confirm marks
    it confirmed (confidence 1, still sewn). Refusals name the seam."""
    import pytest

    from couture.pattern.errors import PatternError
    from couture.pattern.seam_review import drop_seam, seam_rows

    design, rep = build_design(read_pattern(VAL / "TShirt_test_astm.dxf"))
    rows = seam_rows(design)
    assert len(rows) == len(rep.seams) > 5
    assert [r.confidence for r in rows] == sorted(r.confidence for r in rows)  # least sure first
    ui = CoutureUI(UIConfig(port=free_port(), export_dir=tmp_path, show_body=False, draft_locally=False))
    ui.start()
    try:
        ui.set_design(design)
        got: list = []
        ui.on_design_changed = got.append
        panel = ui.seams
        first = rows[0]
        assert f"{first.confidence:.2f} {first.reason}" in panel.table.content
        assert len(panel.choice.options) == len(rows) and first.a in panel.choice.value
        n_seams = len(draft(design).seams)
        panel.act("drop")
        assert len(got) == 1 and first.stroke_id not in {s.id for s in got[-1].strokes}
        assert len(draft(got[-1]).seams) == n_seams - 1
        assert len(panel.choice.options) == len(rows) - 1  # the list follows the committed design
        second = seam_rows(got[-1])[0]
        panel.act("confirm")
        st = next(s for s in got[-1].strokes if s.id == second.stroke_id)
        assert st.params["confirmed"] is True and st.params["confidence"] == 1.0
        assert len(draft(got[-1]).seams) == n_seams - 1  # still sewn
        assert f"| {second.a} + {second.b} | confirmed |" in panel.table.content
    finally:
        ui.stop()
    with pytest.raises(PatternError, match="no seam stroke with that id"):
        drop_seam(design, "nope")
