"""A from-scratch drape of every sloper reaches a dressed equilibrium.

Coarse (400 vertices), default fabric, mannequin with friction, from the
wrap placement. Dressed: relative residual <= 1e-3, no vertex more than 2 mm
inside the body, the garment's top not more than 10 cm below where it was
placed. Not weakened to what the solvers reach today: see
``python -m couture.bench.drape_slopers`` for the numbers.
"""

from __future__ import annotations

import pytest

from couture.bench.drape_slopers import INSIDE_LIMIT, SLID_LIMIT, drape

pytestmark = pytest.mark.slow


# Trousers that stay up. Their top (the waistband's upper edge) settles at
# most SLID["trousers"] below where it was placed, at 400 vertices. Measured
# (newton, this machine): -1.0 cm (the band rises a little) on the default
# mannequin. Before the waistband piece and the rise ease they slid 4.1 cm:
# the crotch, drafted at the body's crotch depth, bore up into the body's
# crotch and pulled the waist down by 1.4 N (more than the trousers' 1.3 N
# weight), and the waist edge, placed 2 cm off the body, found no friction
# anchors before the end of the solve (see ``draft_trousers``).
SLID = {"trousers": 0.01}


@pytest.mark.parametrize("kind", ["skirt", "dress", "shirt", "trousers", "shirt_set_in"])
def test_sloper_drapes_to_a_dressed_equilibrium(kind):
    row, _, _ = drape(kind, vertices=400, solvers=("newton", "kinetic"), max_seconds=10.0, tol=1e-3)
    assert row.min_phi_mm >= INSIDE_LIMIT * 1e3, row
    assert row.top_drop_cm <= SLID.get(kind, SLID_LIMIT) * 100, row
    assert row.residual <= 1e-3, row


def test_trousers_stay_up_on_a_graded_body():
    """The trousers drafted for XS's measurements (waist 62, hip 90 cm, waist
    to hip and to crotch from the body), draped on XS: the waistband, placed at
    XS's own waist, settles at most 1 cm below where it was placed (measured
    0.8 cm, newton, 400 vertices; 6-8 cm before the rise ease and the band)."""
    from couture.bench.drape_slopers import body_params

    params = body_params("trousers", "XS")
    assert params["waist_girth"] == pytest.approx(0.62, abs=1e-3)
    row, _, _ = drape("trousers", vertices=400, max_seconds=10.0, tol=1e-3, params=params, body="XS")
    assert row.residual <= 1e-3, row
    assert row.min_phi_mm >= INSIDE_LIMIT * 1e3, row
    assert row.top_drop_cm <= 1.0, row
