"""A from-scratch drape of every sloper reaches a dressed equilibrium.

Coarse (400 vertices), default fabric, mannequin with friction, from the
wrap placement. Dressed: relative residual <= 1e-3, no vertex more than 2 mm
inside the body, the garment's top not more than 10 cm below where it was
placed. Not weakened to what the solvers reach today: see
``python -m bench.drape_slopers`` for the numbers.
"""

from __future__ import annotations

import pytest

from bench.drape_slopers import INSIDE_LIMIT, SLID_LIMIT, drape

pytestmark = pytest.mark.slow


# Trousers that stay up. Their top (the waistband's upper edge) settles at
# most SLID["trousers"] below where it was placed, at 400 vertices. Measured
# (newton, this machine): -1.4 cm (the band rises a little) on the default
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


@pytest.mark.parametrize("body,waist", [("XS", 0.62), ("XL", 0.78)])
def test_trousers_stay_up_on_a_graded_body(body, waist):
    """The trousers drafted for a graded body's measurements (waist, hip, waist
    to hip, crotch depth and crotch length from the body), draped on it: the
    waistband, placed at the body's own waist, settles at most 1 cm below
    where it was placed. XS is the smallest body, XL the one that slid most
    (newton, 400 vertices: XS -0.5 cm, XL 0.55 cm; 0.8 and 2.4 cm with the rise
    drafted from the crotch depth + 6 cm and the elastic at 0.8 of the waist)."""
    from bench.drape_slopers import body_params

    params = body_params("trousers", body)
    assert params["waist_girth"] == pytest.approx(waist, abs=1e-3)
    row, _, _ = drape("trousers", vertices=400, max_seconds=10.0, tol=1e-3, params=params, body=body)
    assert row.residual <= 1e-3, row
    assert row.min_phi_mm >= INSIDE_LIMIT * 1e3, row
    assert row.top_drop_cm <= 1.0, row
