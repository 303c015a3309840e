"""``couture bench inside``: its measure of the body passing through the cloth
between vertices, on a sphere where the answer is known."""

from __future__ import annotations

import numpy as np

from bench import inside
from couture.cloth import ClothModel, Scene
from couture.cloth.body import SphereBody
from couture.mesh import GarmentMesh
from schemas.design import Fabric

FABRIC = Fabric(stretch_stiffness=50.0, poisson_ratio=0.3, bend_stiffness=1e-4, area_density=0.15)
BALL = SphereBody(center=np.zeros(3), radius=0.03)


def test_a_chord_through_a_thin_part_is_found_and_a_resting_edge_is_not():
    """Both ends 5 mm outside a 3 cm ball: the chord through its middle passes
    30 mm below the surface (through), one lying over the ball does not; an edge
    with an end inside the body is the vertices' business, not counted."""
    x = np.array(
        [
            [-0.035, 0.0, 0.0],
            [0.035, 0.0, 0.0],  # chord through the centre
            [-0.02, 0.036, 0.0],
            [0.02, 0.036, 0.0],  # over the top: its lowest point 6 mm outside
            [-0.02, 0.0, 0.0],  # inside the ball
        ]
    )
    edges = np.array([[0, 1], [2, 3], [4, 1]])
    through, deepest = inside.edges_through(BALL, x, edges, depth=0.01)
    assert through.tolist() == [True, False, False]
    assert deepest[0] < -0.029 and deepest[1] > 0.005


def test_level_trace_counts_the_edges_a_thin_part_passes_through():
    """A strip of two triangles: lying over the ball, no edge goes through; pulled
    down across it with its four vertices still outside, the ball is in the cloth
    (the vertices' contact would see nothing: their phi is positive)."""
    mesh = GarmentMesh(
        X=np.array([[0, 0], [0.08, 0], [0.08, 0.02], [0, 0.02]], float), tris=np.array([[0, 1, 2], [0, 2, 3]])
    )
    model = ClothModel(mesh, FABRIC, Scene(body=BALL, gravity=False))
    over = np.array([[-0.04, 0.04, -0.01], [0.04, 0.04, -0.01], [0.04, 0.04, 0.01], [-0.04, 0.04, 0.01]])
    across = over - np.array([0.0, 0.04, 0.0])
    rows = inside.level_trace(model, [(0, 1.0, over), (1, 0.5, across)])
    # (0, 1), (2, 3) 20 mm below the surface, the diagonal (0, 2) through the centre
    assert [r["edges_through"] for r in rows] == [0, 3]
    assert rows[1]["deepest_vertex_m"] > 0.0 and rows[1]["deepest_edge_point_m"] < -0.02
    assert abs(rows[1]["largest_move_m"] - 0.04) < 1e-12
