"""The A-line skirt: n identical gores hung from the waist."""

from __future__ import annotations

from couture.pattern import options as O
from couture.pattern.geometry import line
from couture.pattern.options import opt
from couture.pattern.slopers.base import MIRROR_X, PanelDef, SegDef, SloperDef, SloperDraft, mirror_panel, torso_ring
from couture.pattern.slopers.parts import hem, skirt_side

SKIRT_OPTIONS = (
    O.WAIST,
    O.HIP,
    O.WAIST_TO_HIP,
    opt("length", 0.60, 0.38, 1.00, "m", "waist to hem at centre"),
    opt("flare", 0.12, 0.0, 0.60, "rad", "angle of each side seam from vertical below the hip"),
    opt("panels", 4, 2, 8, "count", "number of panels (gores); topology option", integer=True),
    opt("waist_ease", 0.01, 0.0, 0.08, "m", "added to the waist girth"),
    opt("hip_ease", 0.04, 0.0, 0.15, "m", "added to the hip girth"),
)


def skirt_panels(prefix_names: list[str], p, ww_total, wh_total, L) -> list[PanelDef]:
    """One gore per name, the waist ``ww_total`` and the hip ``wh_total`` [m]
    shared evenly, ``L`` from waist to hem."""
    n = len(prefix_names)
    side, C, k, f = skirt_side(ww_total / n, wh_total / n, p["waist_to_hip"], L, p["flare"])
    out = []
    for name in prefix_names:
        W = side[-1].pts[-1]
        waist = SegDef("waist", [line(W, W * MIRROR_X)])
        out.append(mirror_panel(name, [SegDef("side_right", side)], waist, hem(C, k, f)))
    return out


def draft_skirt(p: dict[str, float]) -> SloperDraft:
    """A-line skirt of n identical gores; gore 0 centred at the front."""
    n = int(round(p["panels"]))
    names = ["front", "back"] if n == 2 else [f"gore{i}" for i in range(n)]
    panels = skirt_panels(names, p, p["waist_girth"] + p["waist_ease"], p["hip_girth"] + p["hip_ease"], p["length"])
    seams = [(names[i], "side_right", names[(i + 1) % n], "side_left") for i in range(n)]
    return SloperDraft(panels, seams, [torso_ring(names)])


SKIRT = SloperDef("skirt", SKIRT_OPTIONS, draft_skirt, draft_skirt.__doc__ or "")
