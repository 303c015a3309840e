"""The imported-pattern fixtures (tests/data/imported/) are what the real tools
make today: the test set-up drafts them again with
tests/data/imported/make/make.sh (FreeSewing from npm at the lock file's
versions, Valentina from apt), into a cache reused while the script, the lock
file and the tools' versions stay the same, and each freshly drafted file must
import (``read_pattern``, ``build_design``) to the same pieces as the committed
one. Files are compared by geometry, not bytes: Valentina's DXF carries the
export's date and writes its pieces in a varying order.

Skipped only where the package manager refuses (make.sh exits 75: the npm
registry unreachable or refusing a pinned package, apt unable to install
valentina), with its reason; any other failure of the drafting fails."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from couture.cloth.body import cache_dir
from couture.pattern.imported import ImportedPiece, read_pattern
from couture.pattern.sewing import build_design

DATA = Path(__file__).parent / "data" / "imported"
MAKE = DATA / "make"
REFUSED = 75
"""make.sh's exit status when the package manager refused"""
TOLERANCE = 1e-6
"""[m] largest vertex distance between a fresh and a committed piece"""


def _version(*cmd: str) -> str:
    """A tool's version for the cache key ('absent' where it is not installed)."""
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    except FileNotFoundError:
        return "absent"
    return r.stdout.strip() if r.returncode == 0 else "absent"


def _cache_key(part: str) -> str:
    """The script, its inputs and the tool's version: a change of any drafts again."""
    h = hashlib.sha256()
    names = ["make.sh"] + (["freesewing.mjs", "package.json", "package-lock.json"] if part == "freesewing" else [])
    for name in names:
        h.update(name.encode() + b"\0" + (MAKE / name).read_bytes() + b"\0")
    if part == "freesewing":
        h.update(_version("node", "--version").encode())
    else:
        h.update(_version("dpkg-query", "-W", "-f", "${Version}", "valentina").encode())
    return h.hexdigest()[:16]


def _report(config: pytest.Config, line: str) -> None:
    """A line in the test log (not captured): the drafting's cost shows in every CI run."""
    tr = config.pluginmanager.get_plugin("terminalreporter")
    capture = config.pluginmanager.get_plugin("capturemanager")
    if tr is None or capture is None:
        return
    with capture.global_and_fixture_disabled():
        tr.write("\n")
        tr.write_line(line)


def _drafted(part: str, config: pytest.Config) -> Path:
    """The folder holding ``part``/ as make.sh drafts it now: from the cache,
    or drafted into it (into a temporary folder renamed when complete, so a
    half-drafted folder is never reused)."""
    t0 = time.perf_counter()
    root = cache_dir() / "imported-fixtures"
    done = root / f"{part}-{_cache_key(part)}"
    if (done / part).is_dir():
        _report(config, f"[imported fixtures] {part}: reused {done} (warm, {time.perf_counter() - t0:.2f} s)")
        return done
    root.mkdir(parents=True, exist_ok=True)
    tmp = root / f"{done.name}.tmp-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    r = subprocess.run(
        ["bash", str(MAKE / "make.sh"), part, str(tmp), str(tmp / "work")],
        capture_output=True,
        text=True,
        timeout=900,
    )
    seconds = time.perf_counter() - t0
    if r.returncode == REFUSED:
        shutil.rmtree(tmp, ignore_errors=True)
        reason = (r.stderr.strip().splitlines() or ["make.sh gave no reason"])[-1]
        pytest.skip(f"cannot draft the {part} fixtures: {reason}")
    if r.returncode != 0:
        pytest.fail(f"make.sh {part} failed (exit {r.returncode}) after {seconds:.1f} s:\n{r.stderr[-4000:]}")
    shutil.rmtree(tmp / "work")  # the npm tree and raw exports: only the drafted files are kept
    try:
        tmp.rename(done)
    except OSError:  # another session finished first: its folder is as good
        shutil.rmtree(tmp, ignore_errors=True)
    _report(config, f"[imported fixtures] {part}: drafted into {done} (cold, {seconds:.1f} s)")
    return done


@pytest.fixture(scope="session")
def freesewing_drafted(pytestconfig) -> Path:
    return _drafted("freesewing", pytestconfig) / "freesewing"


@pytest.fixture(scope="session")
def valentina_drafted(pytestconfig) -> Path:
    return _drafted("valentina", pytestconfig) / "valentina"


def _committed(tool: str, suffix: str) -> list[str]:
    return sorted(p.name for p in (DATA / tool).glob(f"*{suffix}"))


def _shape_distance(A: np.ndarray, B: np.ndarray) -> float:
    """Largest vertex distance [m] after the best translation (a layout may move pieces)."""
    d = (A - A.mean(0)) - (B - B.mean(0))
    return float(np.abs(d).max())


def _same_pieces(fresh: list[ImportedPiece], committed: list[ImportedPiece], file: str) -> None:
    """The same pieces, named and cut alike, the sew and cut lines within ``TOLERANCE``."""
    assert [p.name for p in fresh] == [p.name for p in committed], file
    for f, c in zip(fresh, committed, strict=True):
        where = f"{file}: {c.name}"
        assert (f.cut_count, f.mirrored, f.on_fold) == (c.cut_count, c.mirrored, c.on_fold), where
        assert f.sew.shape == c.sew.shape, (where, f.sew.shape, c.sew.shape)
        assert _shape_distance(f.sew, c.sew) < TOLERANCE, where
        assert (f.cut is None) == (c.cut is None), where
        if f.cut is not None and c.cut is not None:
            assert f.cut.shape == c.cut.shape and _shape_distance(f.cut, c.cut) < TOLERANCE, where
        assert len(f.notches) == len(c.notches) and len(f.holes) == len(c.holes), where


def _imports_as_committed(fresh: Path, committed: Path) -> None:
    """The fresh file gives the committed file's pieces and builds a design of
    them (the importer's seams, ring and placement; the committed files' designs
    are tested in test_import_place.py and test_import_sewing.py)."""
    pieces = read_pattern(fresh)
    _same_pieces(pieces, read_pattern(committed), fresh.name)
    design, report = build_design(pieces)
    # every piece is in it, whole or as a left and a right ('back_left', 'back_right'),
    # or left out with a note naming it (a binding or facing: two layers at one place)
    built = [p.name for p in design.pieces]
    left_out = " ".join(n for n in report.notes if "left out" in n)
    for p in pieces:
        assert any(b == p.name or b.startswith(p.name + "_") for b in built) or p.name in left_out, (p.name, built)
    assert len(report.seams) > 0, fresh.name
    assert any(p.placement.ring != "flat" for p in design.pieces), fresh.name  # placed round the body


@pytest.mark.parametrize("tool", ["freesewing", "valentina"])
def test_the_committed_files_are_all_drafted(request, tool):
    """make.sh drafts exactly the committed files: none left over, none missing."""
    fresh = request.getfixturevalue(f"{tool}_drafted")
    assert sorted(p.name for p in fresh.iterdir()) == sorted(p.name for p in (DATA / tool).iterdir())


@pytest.mark.parametrize("name", _committed("freesewing", ".svg"))
def test_freesewing_redrafted_as_committed(freesewing_drafted, name):
    """penelope, titan and teagan for two measurement sets each, drafted by
    FreeSewing now: the same pieces and sew lines as the committed SVG, and a design of them."""
    _imports_as_committed(freesewing_drafted / name, DATA / "freesewing" / name)


def test_freesewing_drafts_three_designs_for_two_sets_each():
    """Issue 29's set: a skirt, trousers and a top with sleeves, two sets each
    (and aaron, a sleeveless top with its bindings)."""
    names = _committed("freesewing", ".svg")
    designs = {n.split("_")[0] for n in names}
    assert designs == {"penelope", "titan", "teagan", "aaron"}
    assert all(sum(n.startswith(d + "_") for n in names) == 2 for d in designs)


@pytest.mark.parametrize("name", _committed("freesewing", ".json"))
def test_freesewing_measurement_sets_as_the_models_give_them(freesewing_drafted, name):
    """The committed sets (mm) are @freesewing/models' sets as installed now."""
    fresh = json.loads((freesewing_drafted / name).read_text())
    committed = json.loads((DATA / "freesewing" / name).read_text())
    assert fresh == committed
    assert len(committed) > 20 and 500 < committed["seat"] < 1500  # a whole set, in mm


@pytest.mark.parametrize("name", _committed("valentina", ".dxf"))
def test_valentina_reexported_as_committed(valentina_drafted, name):
    """Keiko's skirt and the T-shirt test, exported by Valentina now (ASTM and
    AAMA): the same pieces, sew and cut lines as the committed DXF, and a design of them."""
    _imports_as_committed(valentina_drafted / name, DATA / "valentina" / name)


def test_valentina_measurements_as_committed(valentina_drafted):
    """keiko.json: Keiko's measurements (cm in keiko.vit) as FreeSewing names, mm."""
    fresh = json.loads((valentina_drafted / "keiko.json").read_text())
    assert fresh == json.loads((DATA / "valentina" / "keiko.json").read_text())
    assert set(fresh) == {"chest", "waist", "seat"} and 500 < fresh["waist"] < fresh["seat"] < 1500


def _make(tmp_path: Path, part: str, env: dict[str, str], script: Path = MAKE / "make.sh"):
    return subprocess.run(
        ["bash", str(script), part, str(tmp_path / "out"), str(tmp_path / "work")],
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, **env},
    )


def test_an_unreachable_registry_is_a_refusal(tmp_path):
    """The one failure that skips: npm cannot reach its registry (here a
    closed port, with an empty npm cache): exit 75, the reason last."""
    r = _make(
        tmp_path,
        "freesewing",
        {
            "npm_config_registry": "http://127.0.0.1:1/",
            "npm_config_fetch_retries": "0",
            "npm_config_cache": str(tmp_path / "npm-cache"),
        },
    )
    assert r.returncode == REFUSED, r.stderr[-2000:]
    assert r.stderr.strip().splitlines()[-1].startswith("package manager refused: npm ci from http://127.0.0.1:1/")
    assert not (tmp_path / "out" / "freesewing" / "penelope_cisFemaleAdult34.svg").exists()


def test_a_failing_draft_is_no_refusal(tmp_path):
    """Any other failure (here the drafting script broken) fails the set-up: exit 1."""
    make = tmp_path / "make"
    shutil.copytree(MAKE, make)
    (make / "freesewing.mjs").write_text("throw new Error('broken draft')\n")
    r = _make(tmp_path, "freesewing", {}, make / "make.sh")
    if r.returncode == REFUSED:
        pytest.skip(f"cannot install FreeSewing: {r.stderr.strip().splitlines()[-1]}")
    assert r.returncode == 1, r.stderr[-2000:]
    assert "broken draft" in r.stderr


def test_apt_refusing_valentina_is_a_refusal(tmp_path):
    """Where valentina is missing and apt cannot install it (here a PATH
    without valentina and an apt-get that cannot find the package): exit 75,
    apt's reason last."""
    bin_ = tmp_path / "bin"
    bin_.mkdir()
    for d in os.environ["PATH"].split(os.pathsep):
        for tool in Path(d).glob("*") if Path(d).is_dir() else []:
            if tool.name not in ("valentina", "apt-get", "sudo") and not (bin_ / tool.name).exists():
                (bin_ / tool.name).symlink_to(tool)
    (bin_ / "apt-get").write_text(
        '#!/bin/sh\n[ "$1" = update ] && exit 0\necho "E: Unable to locate package valentina" >&2\nexit 100\n'
    )
    (bin_ / "sudo").write_text('#!/bin/sh\n[ "$1" = -n ] && shift\nexec "$@"\n')  # as root: no password
    (bin_ / "apt-get").chmod(0o755)
    (bin_ / "sudo").chmod(0o755)
    r = _make(tmp_path, "valentina", {"PATH": str(bin_)})
    assert r.returncode == REFUSED, r.stderr[-2000:]
    last = r.stderr.strip().splitlines()[-1]
    assert last == "package manager refused: apt-get install valentina: E: Unable to locate package valentina"
