"""Reading pattern pieces from other tools' files (couture.pattern.imported):
this project's own DXF/SVG export read back (the round trip), Valentina's
ASTM and AAMA DXF, FreeSewing's SVG (tests/data/imported/, made by
tests/data/imported/make/make.sh with the real tools, committed; drafted again
and compared with these by tests/test_import_redraft.py).

Numbers are checked against something independent of the reader: the drafted
pattern that was exported, the other DXF flavour of the same Valentina file,
and the FreeSewing measurement set the pattern was drafted for."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from couture.pattern.cutting import CutSpec
from couture.pattern.draft import draft
from couture.pattern.geometry import polyline_length, signed_area
from couture.pattern.imported import ImportedPiece, read_pattern
from couture.pattern.io import export_dxf, export_svg
from couture.pattern.sewing import panels_of
from schemas.design import Design, Sloper

DATA = Path(__file__).parent / "data" / "imported"
FS = DATA / "freesewing"
VAL = DATA / "valentina"


def _same_shape(A: np.ndarray, B: np.ndarray) -> float:
    """Largest vertex distance [m] after the best translation (the sheet layout moves pieces)."""
    assert A.shape == B.shape, (A.shape, B.shape)
    d = (A - A.mean(0)) - (B - B.mean(0))
    return float(np.abs(d).max())


@pytest.mark.parametrize("kind", ["skirt", "shirt"])
@pytest.mark.parametrize("units", ["mm", "in"])
def test_own_dxf_round_trip(tmp_path, kind, units):
    """export then import: the same sew lines to 1e-6 m, the same notches,
    grain line, names and cut counts."""
    pat = draft(Design(sloper=Sloper(kind=kind)))
    spec = CutSpec(seam_allowance=0.01, hem_allowance=0.03, group=True, sheet_width=1.2)
    f = tmp_path / "p.dxf"
    pieces = export_dxf(pat, f, units=units, spec=spec)
    got = {g.name: g for g in read_pattern(f)}
    assert sorted(got) == sorted(p.name for p in pieces)
    for p in pieces:
        g = got[p.name]
        shift = g.sew[0] - p.sew[0]
        assert np.abs(g.sew - shift - p.sew).max() < 1e-6
        assert np.abs(g.cut - shift - p.cut).max() < 1e-6
        want_notches = np.array([n.inner for n in p.notches]).reshape(-1, 2)
        assert len(g.notches) == len(want_notches) > 0
        # each read notch is one of the exported ones (order is the file's)
        for q in g.notches - shift:
            assert np.linalg.norm(want_notches - q, axis=1).min() < 1e-6
        assert g.grain is not None and np.abs(g.grain - shift - p.grain).max() < 1e-6
        assert g.cut_count == p.quantity
        assert g.mirrored == (p.quantity == 2)  # 'cut 2': a left and a right
        assert len(g.holes) == len(p.panel.holes)


def test_own_svg_round_trip(tmp_path):
    """The SVG export writes mm with 3 decimals: the sew lines come back to 1e-6 m."""
    pat = draft(Design(sloper=Sloper(kind="shirt")))
    spec = CutSpec(seam_allowance=0.01, hem_allowance=0.03, group=True, sheet_width=1.2)
    f = tmp_path / "p.svg"
    sheet = export_svg(pat, f, spec=spec)
    got = {g.name: g for g in read_pattern(f)}
    assert sorted(got) == sorted(p.name for p in sheet.pieces)  # the scale square is no piece
    for p in sheet.pieces:
        g = got[p.name]
        assert _same_shape(g.sew, p.sew) < 1e-6
        assert len(g.notches) == len(p.notches)
        assert g.cut_count == p.quantity


def _area(p: ImportedPiece) -> float:
    return signed_area(p.sew)


def test_valentina_astm_and_aama_agree():
    """Valentina's ASTM (-f 25: cut line on 1, sew line on 14) and AAMA
    (-f 16: cut line only) exports of one pattern: the same pieces and cut
    lines; the AAMA cut lines less a 1 cm allowance near the ASTM sew lines."""
    for name, n in (("Keiko_skirt", 2), ("TShirt_test", 5)):
        astm = read_pattern(VAL / f"{name}_astm.dxf")
        aama = read_pattern(VAL / f"{name}_aama.dxf")
        assert len(astm) == len(aama) == n
        for a, b in zip(astm, aama, strict=True):
            # no $INSUNITS in these files: mm detected (pieces 15 cm .. 65 cm across)
            assert 0.15 < np.ptp(a.sew, axis=0).max() < 0.65
            assert a.cut is not None and b.cut is not None
            assert _same_shape(a.cut, b.cut) < 1e-9
        if name == "TShirt_test":  # it has seam allowances: the sew line lies inside the cut line
            # Valentina's allowances are 1 cm or less (none on a fold, more on hems): the AAMA cut
            # line less 1 cm lies within the ASTM sew line, and close to it on the big pieces
            inset = read_pattern(VAL / f"{name}_aama.dxf", seam_allowance=0.01)
            big = 0
            for a, b in zip(astm, inset, strict=True):
                assert a.cut is not None and _area(a) < signed_area(a.cut)
                assert _area(b) <= _area(a) * (1 + 1e-4)
                if np.ptp(a.sew, axis=0).min() > 0.2:
                    big += 1
                    assert _area(b) == pytest.approx(_area(a), rel=0.05)
            assert big == 3


def test_valentina_pieces_sharing_one_block_are_read_once():
    """Valentina writes every piece into one block and inserts it once per
    piece: five inserts of five pieces are five pieces, not 25."""
    pieces = read_pattern(VAL / "TShirt_test_astm.dxf")
    assert len(pieces) == 5
    assert len({round(_area(p), 8) for p in pieces}) == 5
    names = [p.name for p in pieces]
    assert len(set(names)) == len(names)


def _widths_at(panels, y):
    """Summed widths [m] of the panels at material height y (their tops at 0)."""
    total = 0.0
    for p in panels:
        P = p.outline
        xs = []
        Q = np.vstack([P, P[:1]])
        for a, b in zip(Q[:-1], Q[1:], strict=True):
            if (a[1] - y) * (b[1] - y) < 0:
                xs.append(a[0] + (y - a[1]) / (b[1] - a[1]) * (b[0] - a[0]))
        if len(xs) >= 2:
            total += max(xs) - min(xs)
    return total


@pytest.mark.parametrize("size", ["cisFemaleAdult34", "cisFemaleAdult42"])
def test_freesewing_penelope(size):
    """A pencil skirt: the seam line, not the allowance; the front cut on the
    fold (unfolded whole), the back cut twice (a left and a right); round
    the seat the panels add up to the measurement set's seat plus a little ease."""
    pieces = {p.name: p for p in read_pattern(FS / f"penelope_{size}.svg")}
    assert set(pieces) == {"front", "back", "waistband"}
    assert pieces["front"].on_fold and pieces["front"].cut_count == 1
    assert pieces["back"].mirrored and pieces["back"].cut_count == 2
    meas = json.loads((FS / f"{size}.json").read_text())
    panels = panels_of([pieces["front"], pieces["back"]])
    assert sorted(p.name for p in panels) == ["back_left", "back_right", "front"]
    top = meas["waistToSeat"] / 1000.0
    seat = meas["seat"] / 1000.0
    girth = _widths_at(panels, -top)
    assert seat < girth < 1.1 * seat, (girth, seat)
    # the seam line is inside the allowance path: the hem is FreeSewing's 'fabric' line, 1 cm in
    front = panels[[p.name for p in panels].index("front")]
    assert polyline_length(front.outline, closed=True) == pytest.approx(
        polyline_length(pieces["front"].sew, closed=True) * 2 - 2 * np.ptp(pieces["front"].sew[:, 1]), rel=0.05
    )


def test_freesewing_titan_and_teagan():
    titan = {p.name: p for p in read_pattern(FS / "titan_cisMaleAdult38.svg")}
    assert set(titan) == {"front", "back"}
    assert all(p.mirrored and p.cut_count == 2 for p in titan.values())
    meas = json.loads((FS / "cisMaleAdult38.json").read_text())
    # the trouser back is longer than the inseam (it reaches the waist)
    assert np.ptp(titan["back"].sew[:, 1]) > meas["inseam"] / 1000.0
    teagan = {p.name: p for p in read_pattern(FS / "teagan_cisFemaleAdult34.svg")}
    assert set(teagan) == {"front", "back", "sleeve"}
    assert teagan["front"].on_fold and teagan["back"].on_fold
    assert teagan["sleeve"].mirrored
    assert len(teagan["sleeve"].notches) >= 1


def test_units_override_and_the_size_check():
    """--units cm on a mm file makes a 6 m piece: refused, with the hint."""
    from couture.pattern.imported import ImportError_

    with pytest.raises(ImportError_, match=r"wrong units\?.*--units"):
        read_pattern(VAL / "Keiko_skirt_astm.dxf", units="cm")
    small = read_pattern(VAL / "Keiko_skirt_astm.dxf", units="mm")
    assert 0.4 < np.ptp(small[0].sew, axis=0).max() < 0.6
