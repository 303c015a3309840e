"""couture's per-triangle stretch against Bartle et al.'s eq. 8, on one triangle by hand.

Eq. 8: ``S = 1 - sqrt((λ1 - 1)² + (λ2 - 1)²)`` with λ the *eigenvalues* of
``t_g t_k⁻¹`` (target triangle times the inverse of the current one, both in
the paper's aligned frames, footnote 1: first edge on the x axis, so both are
upper triangular). ``couture.adjust.geometry.stretch`` takes the *singular
values* of the same matrix (the principal stretches). Upper triangular, the
matrix's eigenvalues are its diagonal: the ratios of the first edges' lengths
and of the heights over them, which a shear leaves alone.

The triangles: current ``p = (0,0,0), (1,0,0), (0,1,0)`` [m]; every
expected value below is worked out in closed form here (not by the numpy
code under test).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from couture.adjust.geometry import frames3, stretch

CURRENT = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
TRI = np.array([[0, 1, 2]])
GAMMA = 0.1
"""shear of the target: x += GAMMA * y"""


def eq8(l1: float, l2: float) -> float:
    return 1.0 - math.sqrt((l1 - 1.0) ** 2 + (l2 - 1.0) ** 2)


def couture(target: np.ndarray, current: np.ndarray, tris: np.ndarray = TRI) -> float:
    return float(stretch(frames3(target, tris), frames3(current, tris))[0])


def paper(target: np.ndarray, current: np.ndarray, tris: np.ndarray = TRI) -> float:
    """Eq. 8 as written: eigenvalues of t_g t_k⁻¹ in the aligned frames (real here: triangular)."""
    F = frames3(target, tris)[0] @ np.linalg.inv(frames3(current, tris)[0])
    lam = np.linalg.eigvals(F)
    assert np.abs(lam.imag).max() < 1e-12
    return eq8(*lam.real)


@pytest.mark.parametrize(("axis", "lam"), [(0, 1.1), (1, 0.95)])
def test_a_pure_stretch_along_an_axis_both_definitions_agree(axis, lam):
    """Along x (the first edge) or y (the height over it): t_g t_k⁻¹ =
    diag(λ, 1) or diag(1, λ), eigen- and singular values alike: S = 1 - |λ - 1|."""
    target = CURRENT.copy()
    target[:, axis] *= lam
    by_hand = 1.0 - abs(lam - 1.0)  # 0.90 for 10 % longer, 0.95 for 5 % shorter
    assert couture(target, CURRENT) == pytest.approx(by_hand, abs=1e-12)
    assert paper(target, CURRENT) == pytest.approx(by_hand, abs=1e-12)


def test_b_a_pure_shear_the_paper_misses_and_couture_counts():
    """Target ``(0,0,0), (1,0,0), (γ,1,0)``: in the aligned frames t_k = I and
    t_g = [[1, γ], [0, 1]]. Eigenvalues 1, 1: the paper's S = 1, blind to
    the shear. Singular values: σ² are the eigenvalues of FᵀF = [[1, γ],
    [γ, 1 + γ²]] (trace 2 + γ², determinant 1), so σ = (√(γ² + 4) ± γ) / 2
    = 1.05125, 0.95125 for γ = 0.1 and S = 1 - √(s (s - 2)), s = √(γ² + 4):
    0.92927."""
    target = CURRENT.copy()
    target[2, 0] = GAMMA
    s = math.sqrt(GAMMA**2 + 4.0)
    sigma = ((s + GAMMA) / 2.0, (s - GAMMA) / 2.0)
    assert sigma == pytest.approx((1.05125, 0.95125), abs=1e-5)
    by_hand = eq8(*sigma)
    assert by_hand == pytest.approx(1.0 - math.sqrt(s * (s - 2.0)), abs=1e-14)
    assert by_hand == pytest.approx(0.92927, abs=1e-5)
    assert paper(target, CURRENT) == pytest.approx(1.0, abs=1e-12)
    assert couture(target, CURRENT) == pytest.approx(by_hand, abs=1e-12)


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' formula, written out."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K)


@pytest.mark.parametrize("angle", [0.3, 2.0])
def test_c_a_rotation_gives_1_for_both(angle):
    """The target is the current triangle turned in its plane about its
    centroid (and then, rigidly, out of it): its aligned frame is the same
    [[1, 0], [0, 1]], so t_g t_k⁻¹ = I and both give S = 1."""
    c = CURRENT.mean(axis=0)
    in_plane = (CURRENT - c) @ _rotation([0.0, 0.0, 1.0], angle).T + c
    assert couture(in_plane, CURRENT) == pytest.approx(1.0, abs=1e-12)
    assert paper(in_plane, CURRENT) == pytest.approx(1.0, abs=1e-12)
    tilted = in_plane @ _rotation([1.0, 2.0, 0.5], 0.7).T + [0.1, 1.2, -0.3]
    assert couture(tilted, CURRENT) == pytest.approx(1.0, abs=1e-12)
    assert paper(tilted, CURRENT) == pytest.approx(1.0, abs=1e-12)


def test_d_relabelled_vertices_change_the_papers_value_not_couturess():
    """The sheared pair of (b), its vertices relabelled: the aligned frames
    start from another edge. Labels (1, 2, 0): first edges (-1, 1) and
    (γ - 1, 1), so λ1 = √((1 - γ)² + 1) / √2 = 0.95131 and (area kept)
    λ2 = 1 / λ1 = 1.05118: S = 0.92937. Labels (2, 0, 1): first edges
    (0, -1) and (-γ, -1), λ1 = √(1 + γ²) = 1.00499, λ2 = 1 / λ1: S =
    0.99296. The paper's value depends on which edge is first (1, 0.92937,
    0.99296); couture's, from the singular values, is 0.92927 for every
    labelling, never above the paper's."""
    target = CURRENT.copy()
    target[2, 0] = GAMMA
    s = math.sqrt(GAMMA**2 + 4.0)
    ours = eq8((s + GAMMA) / 2.0, (s - GAMMA) / 2.0)
    l1 = math.sqrt((1.0 - GAMMA) ** 2 + 1.0) / math.sqrt(2.0)
    l2 = math.sqrt(1.0 + GAMMA**2)
    by_hand = {(0, 1, 2): 1.0, (1, 2, 0): eq8(l1, 1.0 / l1), (2, 0, 1): eq8(l2, 1.0 / l2)}
    assert by_hand[(1, 2, 0)] == pytest.approx(0.92937, abs=1e-5)
    assert by_hand[(2, 0, 1)] == pytest.approx(0.99296, abs=1e-5)
    for labels, p in by_hand.items():
        tris = np.array([labels])
        assert paper(target, CURRENT, tris) == pytest.approx(p, abs=1e-12), labels
        assert couture(target, CURRENT, tris) == pytest.approx(ours, abs=1e-12), labels
        assert ours <= p + 1e-12
    assert max(by_hand.values()) - min(by_hand.values()) > 0.07  # the paper's value is not the triangles'


def test_e_couture_is_never_above_the_paper_while_a_triangle_keeps_a_quarter_of_its_area():
    """σ1 >= λ1 >= λ2 >= σ2 > 0 (real λ: triangular in the aligned frames) and
    σ1 σ2 = λ1 λ2 = d; (x - 1)² + (d/x - 1)² has derivative 2 (x - d/x)(x + d/x - 1) / x,
    >= 0 for x >= √d once d >= 1/4: the singular values' sum of squares is the larger."""
    rng = np.random.default_rng(8)
    checked = 0
    for _ in range(2000):
        current = np.column_stack([rng.normal(size=(3, 2)), np.zeros(3)])
        target = current + 0.3 * rng.normal(size=(3, 3))
        Tt, Tc = frames3(target, TRI)[0], frames3(current, TRI)[0]
        if np.linalg.det(Tt) / np.linalg.det(Tc) < 0.25 or abs(np.linalg.det(Tc)) < 1e-3:
            continue
        assert couture(target, current) <= paper(target, current) + 1e-12
        checked += 1
    assert checked > 1000
