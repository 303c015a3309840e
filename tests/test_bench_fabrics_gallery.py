"""`couture bench drape_fabrics_gallery` on a small skirt in two fabrics: one
shared mesh, a converged drape per fabric, the JSON and the side-by-side
picture written; an unknown fabric refused before any drape."""

from __future__ import annotations

import json
import math

import pytest

from bench import drape_fabrics_gallery as gallery

pytestmark = pytest.mark.timeout(300)

SMALL = {
    "schema": "couture/design/v1",
    "design": {"sloper": {"kind": "skirt", "params": {}}, "resolution": {"coarse_vertices": 300, "fine_vertices": 900}},
}


def test_gallery_drapes_each_fabric_on_one_mesh(tmp_path):
    design = tmp_path / "small_skirt.json"
    design.write_text(json.dumps(SMALL))
    out = tmp_path / "gallery"
    # bench drape's variants stand in for library names here (the library may be absent on this branch)
    args = ["--designs", str(design), "--fabrics", "design,stiff", "--vertices", "300", "--out", str(out)]
    assert gallery.main(args) == 0
    rep = json.loads((out / "drape_fabrics_gallery.json").read_text())
    design_cases = rep["designs"]["small_skirt"]
    assert [c["fabric"] for c in design_cases] == ["design", "stiff"]
    soft, stiff = design_cases
    assert soft["vertices"] == stiff["vertices"] > 0  # one mesh for every fabric
    assert stiff["fabric_values"]["stretch_stiffness"] == 2000.0
    for c in design_cases:
        assert c["converged"] and c["residual"] <= 1e-4 and c["iterations"] > 0
        assert math.isfinite(c["wall_time_s"]) and c["fabric_strain_p98_pct"] > 0
    # the same fit strains a 100x stiffer fabric to a far larger share of its limit
    assert stiff["fabric_strain_p98_pct"] > 10 * soft["fabric_strain_p98_pct"]
    assert (out / "small_skirt.png").stat().st_size > 5000


def test_gallery_refuses_an_unknown_fabric_before_draping(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        gallery.main(["--designs", "default_skirt", "--fabrics", "design,stiff,tweed", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert e.value.code == 2 and "tweed" in err and not (tmp_path / "drape_fabrics_gallery.json").exists()
