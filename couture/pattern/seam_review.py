"""The seams of a design as a pattern maker reviews them: each seam stroke
with the importer's confidence and reason (``couture import`` suggests them,
``couture.pattern.sewing.suggest_seams``), and the two answers to a
suggestion: confirm it (the seam is sewn as before and marked confirmed,
confidence 1) or drop it (the two segments become free edges). Seams drawn
by hand carry no confidence and are listed as such. Bus-free: the UI's
Seams folder (``couture.ui.seams_panel``) calls these."""

from __future__ import annotations

import copy
from dataclasses import dataclass

from couture.pattern.errors import PatternError
from schemas.design import Design, Stroke


@dataclass(frozen=True)
class SeamRow:
    """One seam of a design, for review."""

    stroke_id: str
    a: str
    """'<panel>:<segment>' of side a"""
    b: str
    confidence: float | None
    """the importer's confidence in [0, 1]; None for a seam drawn by hand"""
    reason: str
    """why the importer paired them ('' by hand)"""
    confirmed: bool
    """a person confirmed the suggestion"""

    @property
    def label(self) -> str:
        if self.confirmed:
            how = "confirmed"
        elif self.confidence is None:
            how = "drawn"
        else:
            how = f"{self.confidence:.2f}" + (f" {self.reason}" if self.reason else "")
        return f"{self.a} + {self.b} ({how})"


def seam_rows(design: Design) -> list[SeamRow]:
    """Every seam stroke of the design, the least confident suggestions first
    (those are the ones to check), then the confirmed and hand-drawn ones."""
    rows = []
    for st in design.strokes:
        if st.kind != "seam":
            continue
        p = st.params
        conf = p.get("confidence")
        rows.append(
            SeamRow(
                st.id,
                f"{p.get('a_panel', '')}:{p.get('a_segment', '')}",
                f"{p.get('b_panel', '')}:{p.get('b_segment', '')}",
                float(conf) if isinstance(conf, (int, float)) and not isinstance(conf, bool) else None,
                str(p.get("reason", "")),
                bool(p.get("confirmed", False)),
            )
        )
    unsure = sorted(
        (r for r in rows if r.confidence is not None and not r.confirmed), key=lambda r: r.confidence or 0.0
    )
    return unsure + [r for r in rows if r.confidence is None or r.confirmed]


def _seam(design: Design, stroke_id: str) -> int:
    k = next((k for k, st in enumerate(design.strokes) if st.id == stroke_id), None)
    if k is None or design.strokes[k].kind != "seam":
        seams = [st.id for st in design.strokes if st.kind == "seam"]
        raise PatternError(stroke_id, f"no seam stroke with that id; the seams are {seams}")
    return k


def drop_seam(design: Design, stroke_id: str) -> Design:
    """The design without the seam ``stroke_id`` (its two segments left free)."""
    k = _seam(design, stroke_id)
    d = copy.copy(design)
    d.strokes = design.strokes[:k] + design.strokes[k + 1 :]
    return d


def confirm_seam(design: Design, stroke_id: str) -> Design:
    """The design with the seam ``stroke_id`` marked confirmed (confidence 1;
    the importer's reason kept); the seam sews as before."""
    k = _seam(design, stroke_id)
    st = design.strokes[k]
    params = {**st.params, "confirmed": True, "confidence": 1.0}
    d = copy.copy(design)
    d.strokes = list(design.strokes)
    d.strokes[k] = Stroke(id=st.id, kind=st.kind, panel=st.panel, params=params)
    return d
