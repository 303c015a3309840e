"""``couture bench grading``: one garment on graded bodies, its strain, pressure and ease."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench import grading


def test_principal_stretches_match_a_known_deformation():
    """A triangle mapped by rotation @ diag(1.3, 0.8) (then into 3D) has
    principal stretches 1.3 and 0.8, whatever its shape."""
    rng = np.random.default_rng(3)
    X = rng.normal(size=(3, 2))
    t = 0.7
    R = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    x2 = X @ (R @ np.diag([1.3, 0.8])).T
    # embed in a tilted plane of 3D space
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    x = x2 @ Q[:, :2].T + np.array([0.1, 0.2, 0.3])
    s = grading.principal_stretches(X, np.array([[0, 1, 2]]), x)
    assert np.allclose(s, [[1.3, 0.8]], atol=1e-12)


def test_girth_of_a_cylinder_section_is_its_polygon_perimeter():
    """An open cylinder of radius r as triangles: the section at mid-height is the
    K-gon inscribed in the circle; above its top there is none."""
    K, r = 24, 0.15
    th = 2 * np.pi * np.arange(K) / K
    ring = np.column_stack([r * np.cos(th), np.zeros(K), r * np.sin(th)])
    x = np.concatenate([ring, ring + [0.0, 0.2, 0.0]])
    tris = np.array(
        [[k, (k + 1) % K, K + k] for k in range(K)] + [[(k + 1) % K, K + (k + 1) % K, K + k] for k in range(K)]
    )
    g = grading.girth_at(x, tris, 0.1, centre=np.zeros(2))
    assert g == pytest.approx(2 * K * r * np.sin(np.pi / K), rel=1e-9)
    assert grading.girth_at(x, tris, 0.3) is None


def _tube(cx: float, r: float, K: int = 24, base: int = 0):
    th = 2 * np.pi * np.arange(K) / K
    ring = np.column_stack([cx + r * np.cos(th), np.zeros(K), r * np.sin(th)])
    x = np.concatenate([ring, ring + [0.0, 0.2, 0.0]])
    tris = np.array(
        [[k, (k + 1) % K, K + k] for k in range(K)] + [[(k + 1) % K, K + (k + 1) % K, K + k] for k in range(K)]
    )
    return x, tris + base


def test_girth_of_a_sleeved_garment_is_its_torso_part():
    """A bodice tube round a torso and two sleeve tubes round arms at the same
    height: given the body's torso and arm sections there, the girth is the
    bodice's polygon alone (a sleeve is no bust ease); without them, the hull
    goes round the sleeves too, as it did."""
    K, R, r, a = 24, 0.15, 0.05, 0.25
    body, _ = _tube(0.0, R - 0.01, K)
    arm_l, _ = _tube(-a, r - 0.01, K)
    arm_r, _ = _tube(a, r - 0.01, K)
    xb, tb = _tube(0.0, R, K)
    xl, tl = _tube(-a, r, K, base=len(xb))
    xr, tr = _tube(a, r, K, base=2 * len(xb))
    x = np.concatenate([xb, xl, xr])
    tris = np.concatenate([tb, tl, tr])
    torso = body[:K][:, [0, 2]]
    arms = [arm_l[:K][:, [0, 2]], arm_r[:K][:, [0, 2]]]
    g = grading.girth_at(x, tris, 0.1, centre=np.zeros(2), section=(torso, arms))
    assert g == pytest.approx(2 * K * R * np.sin(np.pi / K), rel=1e-9)
    p = np.array([[0.16, 0.0], [0.21, 0.0], [0.29, 0.0], [0.0, 0.2]])
    assert grading.nearer_torso(p, torso, arms).tolist() == [True, False, False, True]
    everything = grading.girth_at(x, tris, 0.1, centre=np.zeros(2))
    assert everything > g + 2 * (a - R)  # round the sleeves: longer by at least both reaches


def test_grading_on_two_sizes(tmp_path):
    """The default skirt on XS and XL, small coarse meshes: every field is there,
    the maps have one value per triangle; the same skirt, loose on XS (waist
    6 cm, hip 12 cm), slides lower there than on XL (both stand on one floor) and
    keeps more hip ease there (XL hip +16 cm)."""
    rows = grading.run(sizes=["XS", "XL"], vertices=200, progress=lambda s: None)
    assert [r.body for r in rows] == ["XS", "XL"]
    for r in rows:
        assert r.converged, (r.body, r.residual, r.diagnosis)
        assert set(r.ease) == set(grading.LANDMARKS)
        m = len(r.maps["tris"])
        assert r.maps["strain"].shape == (m,) and r.maps["pressure"].shape == (m,)
        assert r.pressure_max >= r.pressure_mean > 0.0
        assert r.strain_max >= r.strain_p95
        assert r.ease["bust"] is None  # a skirt does not reach the bust
    xs, xl = rows
    assert xl.body_girth["hip"] - xs.body_girth["hip"] == pytest.approx(0.16, abs=0.01)
    assert xl.ease["hip"] < xs.ease["hip"], (xs.ease, xl.ease)
    assert xs.top_y < xl.top_y - 0.03, (xs.top_y, xl.top_y)
    # pattern unchanged: the skirt is the same garment on both bodies
    assert xs.vertices == xl.vertices


def test_grading_cli_writes_json_and_png(tmp_path):
    from couture.cli import main

    args = ["bench", "grading", "--sizes", "XL", "--vertices", "150", "--max-step", "0.02", "--out", str(tmp_path)]
    assert main(args) == 0
    data = json.loads((tmp_path / "grading.json").read_text())
    assert data["solver_options"] == {"max_step": 0.02}
    (row,) = data["rows"]
    assert row["body"] == "XL" and "maps" not in row and set(row["ease"]) == {"bust", "waist", "hip"}
    # the skirt drapes clear of the body, in its 1 cm contact layer; its panels are gores
    assert 0.0 < row["clearance"] < 0.011 and row["strain_max_panel"].startswith("gore")
    assert (tmp_path / "grading.png").stat().st_size > 10_000
    with pytest.raises(SystemExit):
        grading.main(["--sizes", "XXXL", "--out", str(tmp_path)])
    for bad in (["--solver", "kinetic", "--max-step", "0.02"], ["--max-step", "0"]):
        with pytest.raises(SystemExit):
            grading.main(["--sizes", "XL", *bad, "--out", str(tmp_path)])


def test_an_arc_is_no_girth():
    """Half the cylinder (one panel's arc): no girth about the axis, though its hull has a perimeter."""
    K, r = 24, 0.15
    th = np.pi * np.arange(K + 1) / K
    ring = np.column_stack([r * np.cos(th), np.zeros(K + 1), r * np.sin(th)])
    x = np.concatenate([ring, ring + [0.0, 0.2, 0.0]])
    n = K + 1
    tris = np.array([[k, k + 1, n + k] for k in range(K)] + [[k + 1, n + k + 1, n + k] for k in range(K)])
    assert grading.girth_at(x, tris, 0.1) is not None
    assert grading.girth_at(x, tris, 0.1, centre=np.zeros(2)) is None
