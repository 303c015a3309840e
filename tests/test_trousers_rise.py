"""The trousers' rise is drafted from the body's crotch length: the centre seam
(band below the waist + front and back centre seams) is the body's crotch
length + crotch ease, for every body, checked on the drafted outline (not on
the solve that drafted it); and the crotch length read from the mesh."""

from __future__ import annotations

import numpy as np
import pytest

from couture.pattern import mannequin as M
from couture.pattern.body_measures import body_options, crotch_length
from couture.pattern.slopers import CROTCH_EASE
from couture.pattern.validate import validate
from schemas.design import Body, Design, Sloper


def _polyline_length(P: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())


def _segment(panel, name):
    seg = next(s for s in panel.segments if s.name == name)
    n = len(panel.outline)
    idx = [(seg.start + k) % n for k in range((seg.stop - seg.start) % n + 1)]
    return panel.outline[idx]


@pytest.mark.parametrize("body", ["default", "XS", "XL"])
def test_centre_seam_is_the_crotch_length_plus_ease(body):
    design = Design(sloper=Sloper(kind="trousers"), body=Body(name=body))
    drafted = validate(design)
    panels = {p.name: p for p in drafted.panels}
    cl = M.CROTCH_LENGTH if body == "default" else body_options(body)["crotch_length"]
    band = np.ptp(_segment(panels["band_front"], "side_left")[:, 1])  # the band's height
    front = _polyline_length(_segment(panels["front_left"], "center"))
    back = _polyline_length(_segment(panels["back_left"], "center"))
    # waist to waist: the band's lower half at front and back, then the two centre seams
    assert band + front + back == pytest.approx(cl + CROTCH_EASE, abs=2e-3)


def test_crotch_length_of_the_bodies():
    """The default's matches its drafting constant; each is longer than twice
    the waist-to-crotch drop (down to the crotch and up again) and the graded
    bodies' grow with their girths (rounder belly and seat)."""
    from couture.bodies import measured

    assert crotch_length("default") == pytest.approx(M.CROTCH_LENGTH, abs=2e-3)
    lengths = []
    for name in ("default", "XS", "S", "M", "L", "XL"):
        m = measured(name)
        cl = crotch_length(name)
        assert 2 * (m["waist_y"] - m["crotch_y"]) < cl < 2 * (m["waist_y"] - m["crotch_y"]) + 0.3, name
        lengths.append(cl)
    assert np.all(np.diff(lengths[1:]) > 0), lengths
