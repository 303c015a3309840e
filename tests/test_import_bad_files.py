"""Bad pattern files: `couture import` says which file, which piece and what
is wrong, exits 4 and writes nothing; malformed DXF and SVG (hypothesis)
either import as valid pieces or raise PatternError, never anything else."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from couture.cli import main
from couture.pattern.errors import PatternError
from couture.pattern.geometry import self_intersections, signed_area
from couture.pattern.imported import MAX_PIECE, MIN_PIECE, read_pattern

DATA = Path(__file__).parent / "data" / "imported"
ROOT = Path(__file__).resolve().parents[1]


def _dxf(path: Path, polys, units: int | None = 4) -> Path:
    """A DXF of loose polylines [(layer, points, closed)] in model space."""
    import ezdxf

    doc = ezdxf.new("R2000")
    if units is not None:
        doc.header["$INSUNITS"] = units
    msp = doc.modelspace()
    for layer, pts, closed in polys:
        msp.add_lwpolyline([tuple(map(float, p)) for p in pts], close=closed, dxfattribs={"layer": layer})
    doc.saveas(str(path))
    return path


def _text(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


SQUARE = [(0, 0), (300, 0), (300, 400), (0, 400)]


def _run(capsys, tmp_path, file: Path, *extra: str) -> tuple[int, str, Path]:
    out = tmp_path / "out" / "design.json"
    rc = main(["import", str(file), "--out", str(out), *extra])
    return rc, capsys.readouterr().err, out


@pytest.mark.parametrize(
    "name,make,want",
    [
        ("text.dxf", lambda p: _text(p, "hello, not a pattern\n"), "neither a DXF"),
        ("empty.dxf", lambda p: _text(p, ""), "the file is empty"),
        ("broken.dxf", lambda p: _text(p, "0\nSECTION\n2\nHEADER\n9\n$ACADVER\n"), "not a readable DXF"),
        ("nopieces.dxf", lambda p: _dxf(p, [("7", [(0, 0), (100, 0)], False)]), "no pieces found"),
        ("open.dxf", lambda p: _dxf(p, [("1", SQUARE, False)]), "open outline"),
        ("bowtie.dxf", lambda p: _dxf(p, [("14", [(0, 0), (300, 400), (300, 0), (0, 400)], True)]), "self-intersects"),
        ("tiny.dxf", lambda p: _dxf(p, [("14", [(0, 0), (5, 0), (5, 5), (0, 5)], True)]), "wrong units"),
        ("huge.dxf", lambda p: _dxf(p, [("14", [(0, 0), (5000, 0), (5000, 400), (0, 400)], True)]), "--units"),
    ],
)
def test_bad_file_exit_4_nothing_written(capsys, tmp_path, name, make, want):
    f = make(tmp_path / name)
    rc, err, out = _run(capsys, tmp_path, f)
    assert rc == 4
    assert str(f) in err and want in err, err
    assert not out.exists() and not out.parent.exists()


def test_bad_piece_is_named(capsys, tmp_path):
    """Two pieces, the second self-intersecting: the message names it."""
    import ezdxf

    doc = ezdxf.new("R2000")
    doc.header["$INSUNITS"] = 4
    for name, pts in (("front", SQUARE), ("back", [(400, 0), (700, 400), (700, 0), (400, 400)])):
        blk = doc.blocks.new(name=name)
        blk.add_lwpolyline(pts, close=True, dxfattribs={"layer": "14"})
        blk.add_lwpolyline(pts, close=True, dxfattribs={"layer": "1"})
        blk.add_text(f"Piece Name: {name}", dxfattribs={"layer": "1", "insert": (pts[0][0] + 10, 200), "height": 5})
        doc.modelspace().add_blockref(name, (0, 0))
    f = tmp_path / "two.dxf"
    doc.saveas(str(f))
    rc, err, out = _run(capsys, tmp_path, f)
    assert rc == 4 and f"{f}:back" in err and "self-intersects" in err, err


def test_wrong_units_then_right_units(capsys, tmp_path):
    """A piece drawn in inches without $INSUNITS, read as mm, is 4 mm across:
    refused with the hint; --units in imports it (7.6 cm x 10.2 cm)."""
    f = _dxf(tmp_path / "in.dxf", [("14", [(0, 0), (3, 0), (3, 4), (0, 4)], True)], units=None)
    rc, err, out = _run(capsys, tmp_path, f, "--units", "mm")
    assert rc == 4 and "wrong units" in err and "4 mm across" in err, err
    rc, err, out = _run(capsys, tmp_path, f, "--units", "in")
    assert rc == 0, err
    from couture.pattern.io import load_design

    P = np.array(load_design(out).pieces[0].outline)
    assert np.ptp(P, axis=0) == pytest.approx([3 * 0.0254, 4 * 0.0254], abs=1e-9)


def test_cli_exit_status_in_a_real_process(tmp_path):
    """The real command line: exit 4 for a bad file, 0 for a FreeSewing skirt."""
    env = {"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"}
    import os

    env = {**os.environ, **env, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    env["COUTURE_CACHE"] = str(tmp_path / "cache")  # the body of the set is built there
    bad = tmp_path / "bad.svg"
    bad.write_text("<svg xmlns='http://www.w3.org/2000/svg'><g><path d='M 0 0 L 10 0 L 10 10'/></g></svg>")
    r = subprocess.run(
        [sys.executable, "-m", "couture", "import", str(bad), "--out", str(tmp_path / "d.json")],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert r.returncode == 4, r.stderr
    assert "no pieces found" in r.stderr
    good = DATA / "freesewing" / "penelope_cisFemaleAdult42.svg"
    body = DATA / "freesewing" / "cisFemaleAdult42.json"
    r = subprocess.run(
        [sys.executable, "-m", "couture", "import", str(good), "--body", str(body), "--out", str(tmp_path / "d.json")],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert r.returncode == 0, r.stderr
    assert "confidence" in r.stdout and "free edges" in r.stdout
    # size 42 (waist 90 cm, seat 115 cm) lies beyond every shipped body: the design names a body of its own
    assert "the set's own body 'cisFemaleAdult42'" in r.stdout and "nearest shipped body 'XL'" in r.stdout
    from couture.pattern.io import load_design

    d = load_design(tmp_path / "d.json")
    assert d.body.name == "cisFemaleAdult42" and d.body.measurements is not None
    assert d.body.measurements["waist_girth"] == 0.9 and d.body.measurements["hip_girth"] == 1.153
    assert len(d.pieces) == 4  # front, back left and right, waistband


# ------------------------------------------------------------------ property tests


def _check_pieces(pieces) -> None:
    """What every imported piece satisfies."""
    assert pieces
    for p in pieces:
        assert p.sew.ndim == 2 and p.sew.shape[1] == 2 and len(p.sew) >= 3
        assert np.all(np.isfinite(p.sew))
        assert signed_area(p.sew) > 0
        size = np.ptp(p.sew, axis=0).max()
        assert MIN_PIECE <= size <= MAX_PIECE
        assert not self_intersections(p.sew)


coords = st.floats(-3000, 3000, allow_nan=False, allow_infinity=False)
poly = st.tuples(
    st.sampled_from(["1", "14", "4", "7", "8", "11", "13", "0"]),
    st.lists(st.tuples(coords, coords), min_size=2, max_size=7),
    st.booleans(),
)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(polys=st.lists(poly, min_size=0, max_size=4), units=st.sampled_from([None, 1, 4, 5, 6]))
def test_random_dxf_imports_or_says_why(tmp_path, polys, units):
    f = _dxf(tmp_path / "r.dxf", polys, units)
    try:
        pieces = read_pattern(f)
    except PatternError as e:
        assert str(f) in str(e)
        return
    _check_pieces(pieces)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cut=st.integers(0, 20000), junk=st.binary(max_size=64))
def test_truncated_or_corrupted_dxf_imports_or_says_why(tmp_path, cut, junk):
    data = (DATA / "valentina" / "Keiko_skirt_astm.dxf").read_bytes()
    f = tmp_path / "t.dxf"
    f.write_bytes(data[:cut] + junk + data[cut + len(junk) :])
    try:
        pieces = read_pattern(f)
    except PatternError as e:
        assert str(f) in str(e)
        return
    _check_pieces(pieces)


svg_cmd = st.tuples(st.sampled_from(["M", "L", "C", "Q", "Z", "l", "H", "V"]), st.lists(coords, max_size=6))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(paths=st.lists(st.lists(svg_cmd, max_size=8), max_size=3), unit=st.sampled_from(["mm", "cm", "in", "", "px"]))
def test_random_svg_imports_or_says_why(tmp_path, paths, unit):
    body = "".join(
        f'<g id="part{i}"><path class="fabric" d="{" ".join(c + " " + " ".join(f"{v:g}" for v in a) for c, a in p)}"/></g>'
        for i, p in enumerate(paths)
    )
    f = tmp_path / "r.svg"
    f.write_text(
        f'<svg xmlns="http://www.w3.org/2000/svg" width="1000{unit}" height="1000{unit}" '
        f'viewBox="0 0 1000 1000">{body}</svg>'
    )
    try:
        pieces = read_pattern(f)
    except PatternError as e:
        assert str(f) in str(e)
        return
    _check_pieces(pieces)


def test_exclude_collects_every_flag_and_every_name():
    """`--exclude A --exclude B` leaves out both (an `--exclude` per piece kept
    only the last), as does `--exclude A B`."""
    from couture.cli import _parser

    for argv in (["--exclude", "a", "--exclude", "b"], ["--exclude", "a", "b"]):
        args = _parser().parse_args(["import", "x.svg", "--out", "y.json", *argv])
        assert args.exclude == ["a", "b"], argv
