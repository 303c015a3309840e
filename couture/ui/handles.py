"""Pattern-view handles: the design's own editable elements, placed where
dragging them visibly does something.

Every handle is one element id of :mod:`couture.pattern.edit` (``param:``,
``cv:``, ``dart:``, ``hole:``), so the remesher can compute Ψ for it, the
sensitivity node can predict, and a release commits with
``apply_edit(design, element, dd)``. Pure module (no viser, no bus).

Placement (the same rule for every sloper): a handle sits on the polyline
vertex that its element moves most, |J_v| = max over the panels' outline
vertices of the Frobenius norm of the element's Jacobian (k, 2, 2). For the
default skirt this puts

- ``param:length`` on the hem (vertices that move straight down),
- ``param:flare`` on a hem corner (swings outward),
- ``param:hip_ease`` on the hip point of a side seam,
- ``param:waist_ease`` on a waist corner,
- ``cv:<panel>:<segment>:<i>`` on its curve stroke's control point,
- ``dart:<id>:position|width|length`` on the dart's mouth centre, leg and apex,
- ``pt:<piece>:<i>`` (an imported piece's corner) on that corner itself, always
  (its Jacobian is exact and costs no draft, so a FreeSewing piece's dozens of
  corners are cheap; its sew-line points between corners get no handle).

Two handles never share a vertex (nor come closer than ``min_gap``): an
element whose best vertex is taken goes to its next best among the vertices
that move at least 80 % as much, preferring the first panel, then the one
farthest from the handles already placed. Body measurements (girths,
heights, widths: the mannequin's, not the garment's style) get no handle:
they stay sliders, and each would cost a Jacobian (two drafts) per design.

Pointer convention (what the ``edit`` message's ``d`` holds):

- ``param:<name>``: the option change dp that moves the handle's vertex as
  close as possible to the pointer: dp = u·Δp / |u|², u = dX_v/dp (the
  handle slides along u, the option's direction at that point); d = [dp, 0].
  E.g. dragging the hem handle down by 5 cm makes the skirt 5 cm longer.
  The value is clamped to the option's [min, max].
- ``cv:``, ``dart:``, ``hole:``, ``pt:``: the pointer displacement Δp [m] itself
  (edit.py splits it in the element's frame).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

log = logging.getLogger("couture.ui.handles")

BODY_OPTION_SUFFIXES = (
    "_girth",
    "waist_to_hip",
    "waist_to_underarm",
    "waist_to_shoulder",
    "shoulder_width",
    "crotch_depth",
    "crotch_length",
)


@dataclass
class Handle:
    """A draggable point of the pattern: one editable element."""

    element: str
    """element id of couture.pattern.edit ('param:length', 'cv:gore0:hem:0', 'dart:d1:width', ...)"""
    panel: str
    vertex: int
    """vertex of ``panel``'s outline (or of its hole ``hole``) the handle sits on"""
    kind: str
    """'param', 'cv', 'dart', 'hole' or 'pt' (a piece's outline point)"""
    u: np.ndarray = field(default_factory=lambda: np.zeros(2))
    """param handles: the vertex's motion per unit option change dX_v/dp [m per option unit], shape (2,)"""
    lo: float = -np.inf
    hi: float = np.inf
    """param handles: the option's range"""
    value: float = 0.0
    """param handles: the option's value at press"""
    hole: int = -1
    """-1: the vertex is on the outline; else the index of the hole polyline"""

    def rest_position(self, panel) -> np.ndarray:
        """The handle's point in panel coordinates [m], shape (2,)."""
        return (panel.outline if self.hole < 0 else panel.holes[self.hole])[self.vertex]

    @property
    def label(self) -> str:
        parts = self.element.split(":")
        if self.kind == "param":
            return parts[1]
        if self.kind == "cv":
            return f"curve {parts[-1]}"
        if self.kind == "pt":
            return f"{parts[1]} corner {parts[-1]}"
        return f"{parts[0]} {parts[-1]}"

    def element_delta(self, d_pointer: np.ndarray) -> np.ndarray:
        """The edit's d for a pointer displacement Δp [m] since press, shape (2,)."""
        d_pointer = np.asarray(d_pointer, np.float64).reshape(2)
        if self.kind != "param":
            return d_pointer.copy()
        uu = float(self.u @ self.u)
        dp = float(self.u @ d_pointer) / uu if uu > 0 else 0.0
        dp = float(np.clip(self.value + dp, self.lo, self.hi) - self.value)
        return np.array([dp, 0.0])


@dataclass
class HandleSet:
    handles: list[Handle]
    jacobians: dict[str, dict]
    """element -> {panel: PanelJacobian}: the outline motion per unit element d"""

    def moved_outlines(self, pattern, element: str, dd: np.ndarray) -> dict[str, np.ndarray]:
        """Outlines after an edit, to first order: X + J @ dd, per panel."""
        J = self.jacobians.get(element, {})
        dd = np.asarray(dd, np.float64).reshape(2)
        out = {}
        for p in pattern.panels:
            pj = J.get(p.name)
            if pj is not None and pj.outline.shape[0] == len(p.outline):
                out[p.name] = p.outline + pj.outline @ dd
            else:
                out[p.name] = p.outline
        return out


def _element_kind(element: str) -> str:
    return element.split(":", 1)[0]


def _is_body_option(element: str) -> bool:
    return element.startswith("param:") and element[6:].endswith(BODY_OPTION_SUFFIXES)


def _inside_range(design, element: str, options: dict):
    """The design with a ``param:`` option at its bound moved just inside (the
    Jacobian is a central difference; a step outside the range is rejected)."""
    import copy

    if not element.startswith("param:") or element[6:] not in options:
        return design
    o = options[element[6:]]
    from couture.ui.state import option_values

    v = float(option_values(design).get(o.name, o.default))
    margin = 1e-5 * max(o.max - o.min, 1e-9)
    inside = min(max(v, o.min + margin), o.max - margin)
    if inside == v:
        return design
    d = copy.deepcopy(design)
    d.sloper.params = {**d.sloper.params, o.name: inside}
    return d


def plan_handles(design, pattern, *, min_gap: float = 0.03, near: float = 0.8) -> HandleSet:
    """Handles for every editable element of ``design`` (drafted as ``pattern``)."""
    from couture.pattern import edit_elements, edit_jacobian
    from couture.pattern.slopers import SLOPERS

    try:
        elements = edit_elements(design)
    except Exception as e:  # an invalid design has no handles (the remesher names the error)
        log.warning("no handles: %s", e)
        return HandleSet([], {})
    options = {o.name: o for o in SLOPERS[design.sloper.kind].options} if design.sloper.kind in SLOPERS else {}
    from couture.ui.state import option_values

    params = option_values(design)
    # strokes first (their vertex is unambiguous), then the style options
    order = [e for e in elements if _element_kind(e) != "param"] + [
        e for e in elements if _element_kind(e) == "param" and not _is_body_option(e)
    ]
    panels = {p.name: p for p in pattern.panels}
    names = [p.name for p in pattern.panels]
    taken: list[tuple[str, np.ndarray]] = []
    handles, jacobians = [], {}
    for el in order:
        try:
            J = edit_jacobian(_inside_range(design, el, options), el)
        except Exception as e:
            log.warning("no Jacobian for %s: %s", el, e)
            continue
        jacobians[el] = J
        best: list[tuple[float, int, str, int, int]] = []
        for pi, name in enumerate(names):
            pj, pn = J.get(name), panels[name]
            if pj is None or pj.outline.shape[0] != len(pn.outline):
                continue
            polys = [(-1, pj.outline)] + [
                (k, hj) for k, hj in enumerate(pj.holes) if k < len(pn.holes) and hj.shape[0] == len(pn.holes[k])
            ]
            for hole, jac in polys:
                mag = np.linalg.norm(jac.reshape(len(jac), -1), axis=1)
                for vi in np.flatnonzero(mag > 1e-9):
                    best.append((float(mag[vi]), pi, name, int(vi), hole))
        if not best:
            continue
        top = max(b[0] for b in best)
        kind = _element_kind(el)
        if kind == "pt":  # a piece point's handle is that point, wherever the others are
            own = el.split(":")
            cands = [b for b in best if b[2] == own[1] and b[3] == int(own[2]) and b[4] < 0] or [
                b for b in best if b[0] >= top
            ]
        else:
            cands = [b for b in best if b[0] >= near * top]

        def at(b) -> np.ndarray:
            pn = panels[b[2]]
            return (pn.outline if b[4] < 0 else pn.holes[b[4]])[b[3]]

        def free(b) -> float:
            p = at(b)
            ds = [float(np.linalg.norm(p - q)) for n, q in taken if n == b[2]]
            return min(ds) if ds else np.inf

        ok = cands if kind == "pt" else [b for b in cands if free(b) >= min_gap] or cands
        # first panel, then farthest from placed handles, then moves most
        b = min(ok, key=lambda b: (b[1], -min(free(b), 1e3), -b[0]))
        _, _, name, v, hole = b
        h = Handle(el, name, v, kind, hole=hole)
        if kind == "param":
            opt = options.get(el[6:])
            jac = J[name].outline if hole < 0 else J[name].holes[hole]
            h.u = jac[v][:, 0].copy()
            if opt is not None:
                h.lo, h.hi, h.value = opt.min, opt.max, float(params.get(opt.name, opt.default))
        handles.append(h)
        taken.append((name, at(b)))
    return HandleSet(handles, jacobians)
