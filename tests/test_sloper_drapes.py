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


# The trousers hang from an elastic waistband (the sloper's ``waistband``
# option, default 0.8: the waist edge cut to 80 % of waist + ease). It settles
# 3.8-4.1 cm below its placed top at 400 vertices, both solvers (without the
# elastic they slid 10.7-11.6 cm to the upper hip): friction carries < 1 % of
# the weight there, the body's waist-to-hip slope the rest (see the issue
# note), so their bound is stated apart, with about 1 cm of margin.
SLID = {"trousers": 0.05}


@pytest.mark.parametrize("kind", ["skirt", "dress", "shirt", "trousers", "shirt_set_in"])
def test_sloper_drapes_to_a_dressed_equilibrium(kind):
    row, _, _ = drape(kind, vertices=400, solvers=("newton", "kinetic"), max_seconds=10.0, tol=1e-3)
    assert row.min_phi_mm >= INSIDE_LIMIT * 1e3, row
    assert row.top_drop_cm <= SLID.get(kind, SLID_LIMIT) * 100, row
    assert row.residual <= 1e-3, row
