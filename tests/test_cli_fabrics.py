"""``couture fabrics`` and the library names where designs are made
(``couture drape --fabric``, ``--panel-fabric``, ``couture import --fabric``)."""

from __future__ import annotations

import json

import pytest

from couture import fabrics
from couture.cli import main, parse_panel_fabrics, with_library_fabrics
from couture.client import load_design
from couture.pattern.io import EXAMPLES


def test_couture_fabrics_lists_the_library(capsys):
    assert main(["fabrics"]) == 0
    out = capsys.readouterr().out
    for name in fabrics.names():
        assert f"\n{name} " in "\n" + out
    assert "bend warp" in out and "measured" in out  # the header and the measured column


def test_couture_fabrics_source_names_every_number(capsys):
    assert main(["fabrics", "--source", "wool_suiting"]) == 0
    out = capsys.readouterr().out
    for field in fabrics.NUMBERS:
        assert f"  {field} " in out
    assert "measured: SiroFAST-2 bending length 15.00 mm" in out


def test_couture_fabrics_json(capsys):
    assert main(["fabrics", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in rows] == fabrics.names()
    assert rows[0]["fabric"]["warp_stiffness"] > 0 and rows[0]["sources"]["warp_stiffness"]


def test_an_unknown_fabric_is_refused_naming_the_library(capsys):
    assert main(["fabrics", "--source", "tweed"]) == 1
    assert "unknown fabric 'tweed'" in capsys.readouterr().err


def test_the_design_takes_library_fabrics_by_name():
    design = load_design(EXAMPLES / "default_skirt.json")
    d = with_library_fabrics(design, "denim", {})
    assert d.fabric == fabrics.get("denim") and d.panel_fabrics == {}
    from couture.pattern.draft import draft

    panel = draft(design).panels[0].name
    d = with_library_fabrics(design, None, {panel: "chiffon"})
    assert d.fabric == design.fabric and d.panel_fabrics == {panel: fabrics.get("chiffon")}
    with pytest.raises(ValueError, match="no panel 'cuff'"):
        with_library_fabrics(design, None, {"cuff": "denim"})
    with pytest.raises(ValueError, match="unknown fabric"):
        with_library_fabrics(design, "tweed", {})


def test_panel_fabric_items_parse():
    assert parse_panel_fabrics(["waistband=denim", "front=chiffon"]) == {"waistband": "denim", "front": "chiffon"}
    with pytest.raises(ValueError, match="PANEL=NAME"):
        parse_panel_fabrics(["waistband"])


def test_drape_refuses_an_unknown_fabric_before_starting_nodes(tmp_path, capsys):
    rc = main(["drape", str(EXAMPLES / "default_skirt.json"), "--out", str(tmp_path / "o"), "--fabric", "tweed"])
    assert rc != 0 and "unknown fabric 'tweed'" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
