"""A body part through the cloth between vertices (``edges_through_body``), and
Newton's answer to it from a placement: damped dynamics from the placement,
their drape taken only when fewer edges pass through the body."""

from __future__ import annotations

import numpy as np
from solver_testmodel import fabric

from couture.cloth import ClothModel, Scene
from couture.cloth.body import SphereBody
from couture.mesh import GarmentMesh, grid_sheet
from couture.solvers import get_solver
from couture.solvers.common import edges_through_body, verdict

BALL = SphereBody(center=np.zeros(3), radius=0.03)


def strip(x: np.ndarray) -> tuple[ClothModel, np.ndarray]:
    mesh = GarmentMesh(
        X=np.array([[0, 0], [0.08, 0], [0.08, 0.02], [0, 0.02]], float), tris=np.array([[0, 1, 2], [0, 2, 3]])
    )
    return ClothModel(mesh, fabric(), Scene(body=BALL, gravity=False)), x


def test_edges_through_body_counts_a_ball_inside_the_cloth_that_vertices_miss():
    """Four vertices 11 mm outside a 3 cm ball (no contact force on any: the layer
    is 10 mm), the strip across its middle: three edges pass 20-30 mm below the
    surface. Lying over the ball, none; no body, none."""
    over = np.array([[-0.04, 0.04, -0.01], [0.04, 0.04, -0.01], [0.04, 0.04, 0.01], [-0.04, 0.04, 0.01]])
    model, _ = strip(over)
    across = over - np.array([0.0, 0.04, 0.0])
    assert np.abs(model.forces(across, ["contact"])).max() == 0.0
    assert edges_through_body(model, across) == 3
    assert edges_through_body(model, over) == 0
    bare = ClothModel(model.mesh, fabric(), Scene(gravity=False))
    assert edges_through_body(bare, across) == 0


def hammock(n: int, radius: float, gap: float, size: float = 0.4) -> ClothModel:
    """A square sheet held along two opposite edges, flat ``gap`` above a ball."""
    m = grid_sheet(size, size, n, n)
    X = m.X
    m.x0 = np.column_stack([X[:, 0] - size / 2, np.full(len(X), radius + gap), X[:, 1] - size / 2])
    m.pinned = np.nonzero((X[:, 0] < 1e-9) | (X[:, 0] > size - 1e-9))[0].astype(np.int32)
    body = SphereBody(center=np.zeros(3), radius=radius)
    return ClothModel(m, fabric(stretch=50.0, bend=1e-6), Scene(body=body))


def test_newton_from_a_placement_tries_dynamics_when_the_body_ends_inside_the_cloth():
    """A ball narrower than the sheet's 8 cm cells, under a cell's middle: the sheet
    sags over it with no vertex touching, and every solver's balance has the
    ball through a cell (vertex contact cannot hold it). Newton sees that,
    runs damped dynamics from the placement, finds them no better and keeps
    its own drape, still converged."""
    model = hammock(5, 0.03, 0.01)
    res = get_solver("newton").solve(model, model.mesh.x0, tol=1e-6, max_seconds=60, from_placement=True)
    assert res.converged, res.diagnosis
    assert res.stats["edges_through_body"] >= 1 and res.stats["dynamics_from_placement_steps"] > 0
    assert res.stats["edges_through_body_dynamics"] >= res.stats["edges_through_body"]
    assert edges_through_body(model, res.x) == res.stats["edges_through_body"]
    ok, _, why = verdict(model, res.x, 1e-6)
    assert ok, why


def test_newton_runs_no_dynamics_when_the_cloth_rests_on_the_body():
    """The same sheet over a ball under a vertex rests on it: nothing through the
    cloth, no dynamics, nothing recorded."""
    model = hammock(4, 0.03, 0.012)
    res = get_solver("newton").solve(model, model.mesh.x0, tol=1e-6, max_seconds=60, from_placement=True)
    assert res.converged, res.diagnosis
    assert edges_through_body(model, res.x) == 0
    assert "edges_through_body" not in res.stats and "dynamics_from_placement_steps" not in res.stats
    assert np.linalg.norm(res.x, axis=1).min() > 0.03


def test_a_solve_request_from_the_placement_is_solved_as_one():
    """``solve_once`` (a solver node's solve request, pattern adjustment's
    solves): a warm start equal to the mesh's placement, or none, takes the
    placement's path (the surface guard and the check for the body between
    vertices, seen here in the stats); any other warm start does not."""
    from couture.solvers.service import solve_once

    newton = get_solver("newton")
    for warm in (None, "x0"):
        model = hammock(5, 0.03, 0.01)
        x_warm = None if warm is None else model.mesh.x0.copy()
        res = solve_once(newton, model, x_warm, tol=1e-6, max_seconds=60)
        assert res.stats.get("edges_through_body", 0) >= 1, (warm, res.stats)
    model = hammock(5, 0.03, 0.01)
    moved = model.mesh.x0 + np.array([0.0, 1e-4, 0.0])
    res = solve_once(newton, model, moved, tol=1e-6, max_seconds=60)
    assert "edges_through_body" not in res.stats and "dynamics_from_placement_steps" not in res.stats
