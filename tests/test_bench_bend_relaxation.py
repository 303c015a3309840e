"""``couture bench bend_relaxation`` (what ``BEND_CONSTANT`` is calibrated on):
its quick run, and its cylinder map and lattices against their definitions."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bench import bend_relaxation as br


def test_the_cylinder_map_is_an_isometry_of_the_sheet():
    """Every edge keeps its length to second order in h / R on the cylinder;
    the points lie at distance R from its axis."""
    X = np.random.default_rng(0).uniform(0.0, 0.1, size=(200, 2))
    R, angle, c = 0.05, math.radians(30), np.array([0.05, 0.05])
    x = br.cylinder_map(X, R, angle, c)
    d = np.array([math.cos(angle), math.sin(angle), 0.0])
    # the axis is parallel to the generators (in-plane, perpendicular to d) through (0, 0, R)
    rel = x - np.array([0.0, 0.0, R])
    gen = np.array([-math.sin(angle), math.cos(angle), 0.0])
    radial = rel - np.outer(rel @ gen, gen)
    np.testing.assert_allclose(np.linalg.norm(radial, axis=1), R, rtol=1e-12)
    s = (X - c) @ d[:2]
    np.testing.assert_allclose(np.arctan2(x[:, :2] @ d[:2], R - x[:, 2]), s / R, atol=1e-12)


def test_the_lattices_have_the_shapes_they_claim():
    eq = br.structured_grid(0.05, 11, equilateral=True)
    e = eq.tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    lengths = np.linalg.norm(eq.X[e[:, 0]] - eq.X[e[:, 1]], axis=1)
    np.testing.assert_allclose(lengths, 0.005, rtol=1e-12)
    right = br.structured_grid(0.05, 11, equilateral=False)
    assert len(right.tris) == 2 * 10 * 10 and len(br.border_vertices(right.tris)) == 40


def test_quick_run_measures_the_relaxation(tmp_path):
    """Two meshes (a triangle sheet, a remesher panel), R = 10 cm, two
    directions: the relaxed interior keeps 0.92-0.96 of the imposed bend's
    energy (the full run's per-kind means 0.934-0.942 of the continuum,
    ``BEND_RELAXED_RESPONSE``), every Newton solve converged."""
    assert br.main(["--quick", "--out", str(tmp_path)]) == 0
    d = json.loads((tmp_path / "bend_relaxation.json").read_text())
    assert {r["kind"] for r in d["rows"]} == {"grid_sheet", "remesher_panel"} and len(d["rows"]) == 4
    for r in d["rows"]:
        assert r["residual"] < 1e-9, r
        assert 0.90 < r["window_relaxed_over_imposed"] < 0.97, r
        assert r["window_imposed_over_continuum"] == pytest.approx(1.0, abs=0.06), r
    assert d["energies_at_c"] == 0.29 and d["bend_constant"] == pytest.approx(0.29 / 0.938)
