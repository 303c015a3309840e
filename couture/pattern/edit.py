"""Edit elements, their Jacobians (SC §6 Ψ on the polyline vertices) and edits.

Element ids:

- ``param:<name>``: a sloper option; ``dd[0]`` is the option change (its unit),
  ``dd[1]`` is ignored. Its Jacobian is the derivative of every polyline
  vertex w.r.t. the option stored in column 0 of the (k, 2, 2) tensor; column 1
  is zero.
- ``cv:<panel>:<segment>:<i>``: control point i of the curve stroke on that
  segment; the pointer motion is split in the segment's frame at the control
  point: along the segment changes its fraction s (ds = t.dd / L), across it
  changes its normal displacement (d dn = n.dd).
- ``dart:<id>:position``: boundary dart slides along its segment (t.dd / L);
  interior dart/hole moves with the pointer (position along the anchor and
  depth from it).
- ``dart:<id>:width``: the pointer drags one side: width changes by 2 t.dd.
- ``dart:<id>:length``: the pointer drags the apex/tip: boundary: length
  changes by a.dd, interior: 2 a.dd (a the inward axis).
- ``hole:<id>:position``, ``hole:<id>:radius`` (radius changes by t.dd).
- ``pt:<piece>:<i>``: outline point i of a free-form piece (``Design.pieces``)
  moves with the pointer (dd itself, [m]); the points between it and the
  nearest corner on either side follow by their arc-length fraction toward
  that corner (``couture.pattern.pieces.point_weights``: a corner's two
  segments stretch to it, a straight edge stays straight, the other corners
  stay), and so do the piece's notches on those runs. A move that makes the
  outline self-intersect is refused, naming the piece and the point. The
  UI's handles are the pieces' corners (:func:`edit_elements`); any point may
  be edited through the id. A piece of a 'Cut 2' pair (``Piece.mirror_of``)
  moves its twin's mirror points with it, x mirrored, so the pair stays one
  piece cut twice; a curve stroke's control point (``cv:``) likewise bends
  the twin's mirror segment (``couture.pattern.pieces.with_mirrored_curve``).
  Its Jacobian is exact (the weights times the 2x2 identity for the piece's
  panel, times diag(-1, 1) for its twin's, the other panels zero) when no
  stroke but a seam names either; else the central differences below.

Jacobians are central finite differences of the drafting function with step
h = 1e-6 in each scalar stroke/option value (metres or fractions): drafting
is a smooth (polynomial / spline / trigonometric) function of these values,
so the truncation error is ~ h^2 |X'''| / 6 ~ 1e-12 m relative to a 1 m
scale, and the round-off error ~ eps |X| / h ~ 1e-10: both far below the
remesher's needs. The pointer-to-value map (frames above) is evaluated once
at the current design and is the same in :func:`apply_edit`, so
``apply_edit(design, e, dd)`` moves the polylines by ``J @ dd`` to first order.
"""

from __future__ import annotations

import copy

import numpy as np

from couture.pattern.draft import DraftContext, draft_with_context, interior_frame, sloper_of
from couture.pattern.drafted import DraftedPattern, PanelJacobian
from couture.pattern.errors import PatternError
from couture.pattern.geometry import self_intersections, signed_area
from couture.pattern.pieces import MIRROR, mirror_twin, point_weights, twin_points, with_mirrored_curve
from schemas.design import Design, Piece, Stroke

FD_STEP = 1e-6


def _curve_stroke(design: Design, panel: str, segment: str, element: str) -> Stroke:
    for st in design.strokes:
        if st.kind == "curve" and st.panel == panel and st.params.get("segment") == segment:
            return st
    raise PatternError(element, f"no curve stroke on {panel}:{segment}")


def _dart_params(design: Design, ctx: DraftContext, dart_id: str, element: str) -> tuple[dict, str]:
    if dart_id not in ctx.darts:
        raise PatternError(element, f"no dart or hole with id {dart_id!r}; ids are {sorted(ctx.darts)}")
    d = ctx.darts[dart_id]
    return d.params, d.kind


def _piece_point(design: Design, element: str) -> tuple[int, Piece, int]:
    """(piece index, piece, outline index) of a ``pt:<piece>:<i>`` element."""
    parts = element.split(":")
    if len(parts) != 3:
        raise PatternError(element, "a piece point is pt:<piece>:<outline index>")
    j = next((j for j, pc in enumerate(design.pieces) if pc.name == parts[1]), None)
    if j is None:
        raise PatternError(element, f"no piece named {parts[1]!r}; pieces are {[pc.name for pc in design.pieces]}")
    try:
        i = int(parts[2])
    except ValueError:
        raise PatternError(element, f"outline index {parts[2]!r} is not a whole number") from None
    return j, design.pieces[j], i


def _moved_points(design: Design, element: str) -> list[tuple[int, np.ndarray, np.ndarray, np.ndarray]]:
    """Per piece a ``pt:`` edit moves: (piece index, outline indices, weights,
    the 2x2 map of the pointer's motion onto theirs): the piece's own points
    (the identity), and for a 'Cut 2' pair its twin's mirror points (x mirrored)."""
    j, piece, i = _piece_point(design, element)
    idx, w = point_weights(piece, i, element)
    out = [(j, idx, w, np.eye(2))]
    twin = mirror_twin(design, piece)
    if twin is not None:
        out.append((twin[0], twin_points(piece, idx), w, np.diag(MIRROR)))
    return out


def _point_dofs(design: Design, element: str):
    """(setter, q, G) of a piece point: q its position [m], G the identity.
    A 'Cut 2' twin's points move with it, mirrored."""
    _, piece, i = _piece_point(design, element)
    moved = _moved_points(design, element)  # checks the index first
    q0 = np.asarray(piece.outline[i], float).copy()
    moves = []
    for j, idx, w, A in moved:
        P0 = np.asarray(design.pieces[j].outline, float)
        # a notch follows the outline point nearest it (its weight)
        N0 = np.asarray(design.pieces[j].notches, float).reshape(-1, 2)
        wv = np.zeros(len(P0))
        wv[idx] = w
        wn = wv[np.argmin(np.linalg.norm(N0[:, None, :] - P0[None, :, :], axis=2), axis=1)] if len(N0) else np.zeros(0)
        moves.append((j, idx, w, A, P0, N0, wn))

    def set_point(d, q):
        delta = np.asarray(q, float) - q0
        d = copy.deepcopy(d)
        pieces = list(d.pieces)
        for j, idx, w, A, P0, N0, wn in moves:
            dj = A @ delta
            P = P0.copy()
            P[idx] += w[:, None] * dj[None, :]
            N = N0 + wn[:, None] * dj[None, :]
            pieces[j] = copy.deepcopy(pieces[j])
            pieces[j].outline = [(float(x), float(y)) for x, y in P]
            pieces[j].notches = [(float(x), float(y)) for x, y in N]
        d.pieces = pieces
        return d

    return set_point, q0, np.eye(2)


def _dofs(design: Design, element: str, ctx: DraftContext | None):
    """(setter, values q, G) for an element: q are the scalar values the element
    changes, G (len(q), 2) maps a pointer motion dd to dq; setter(design, q) -> Design.
    The setter takes any q (the Jacobian differences across an option's bound);
    :func:`_bounds` gives the range an edit may commit."""
    parts = element.split(":")
    kind = parts[0]
    if kind == "pt":
        return _point_dofs(design, element)
    assert ctx is not None, "only a piece point's frame needs no draft"
    if kind == "param":
        name = ":".join(parts[1:])
        sd = sloper_of(design)
        opt = next((o for o in sd.options if o.name == name), None)
        if opt is None:
            raise PatternError(element, f"sloper {design.sloper.kind!r} has no option {name!r}")
        if opt.integer:
            raise PatternError(element, f"option {name!r} is a whole number (topology); it has no Jacobian")

        def set_param(d, q):
            d = copy.deepcopy(d)
            d.sloper.params = dict(d.sloper.params)
            d.sloper.params[name] = float(q[0])
            return d

        return set_param, np.array([ctx.params[name]]), np.array([[1.0, 0.0]])
    if kind == "cv" and len(parts) == 4:
        panel, segment, index = parts[1], parts[2], parts[3]
        st = _curve_stroke(design, panel, segment, element)
        try:
            i = int(index)
            s, dn = st.params["points"][i]
        except (ValueError, IndexError, TypeError):
            raise PatternError(element, "no such control point") from None
        seg = ctx.segs[(panel, segment)]
        disp, seg.disp = seg.disp, None  # frame of the base segment
        T = seg.tangent(np.array([float(s)]))[0]
        seg.disp = disp
        L = seg.length()
        t = T / np.linalg.norm(T)
        n = np.array([t[1], -t[0]])
        sid = st.id

        def set_cv(d, q):
            d = copy.deepcopy(d)
            for x in d.strokes:
                if x.id == sid:
                    pts = [list(p) for p in x.params["points"]]
                    pts[i] = [float(q[0]), float(q[1])]
                    x.params = {**x.params, "points": pts}
            return with_mirrored_curve(d, sid)  # a 'Cut 2' twin's segment bends with it

        return set_cv, np.array([float(s), float(dn)]), np.vstack([t / L, n])
    if kind in ("dart", "hole") and len(parts) >= 3:
        did, what = ":".join(parts[1:-1]), parts[-1]
        prm, dkind = _dart_params(design, ctx, did, element)
        panel = ctx.darts[did].panel
        if dkind == "boundary":
            on = ctx.segs.get((panel, str(prm.get("segment"))))
            if on is None:
                raise PatternError(element, f"segment {prm.get('segment')!r} not on panel {panel!r}")
            pos = float(prm["position"])
            T = on.tangent(np.array([pos]))[0]
            t = T / np.linalg.norm(T)
            a = np.array([-t[1], t[0]])
            L = on.length()
            table = {
                "position": (["position"], np.array([t / L])),
                "width": (["width"], np.array([2 * t])),
                "length": (["length"], np.array([a])),
            }
        else:
            _, t, a, L = interior_frame(ctx, panel, prm, element)
            table = {
                "position": (["position", "depth"], np.vstack([t / L, a])),
                "width": (["width"], np.array([2 * t])),
                "length": (["length"], np.array([2 * a])),
                "radius": (["radius"], np.array([t])),
            }
        if what not in table or any(k not in prm for k in table[what][0]):
            raise PatternError(element, f"{dkind} {did!r} has no editable {what!r}")
        keys, G = table[what]
        base = dict(prm)

        def set_dart(d, q):
            d = copy.deepcopy(d)
            new = {**base, **{k: float(v) for k, v in zip(keys, q, strict=True)}}
            for x in d.strokes:
                if x.id == did:
                    x.params = {**x.params, **{k: float(v) for k, v in zip(keys, q, strict=True)}}
                    return d
            # a built-in sloper dart: add an override stroke with the same id
            d.strokes = list(d.strokes) + [Stroke(id=did, kind="dart", panel=panel, params={k: new[k] for k in keys})]
            return d

        return set_dart, np.array([float(prm[k]) for k in keys]), G
    raise PatternError(element, "unknown element id (expected param:, cv:, dart:, hole: or pt:)")


def _bounds(design: Design, element: str, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) (n,) of the values an edit of ``element`` may commit: a sloper
    option's [min, max]; unbounded otherwise (validation judges the result)."""
    lo, hi = np.full(n, -np.inf), np.full(n, np.inf)
    if element.startswith("param:"):
        name = element[len("param:") :]
        opt = next((o for o in sloper_of(design).options if o.name == name), None)
        if opt is not None:
            lo[:], hi[:] = opt.min, opt.max
    return lo, hi


def _stack(p: DraftedPattern):
    return {pn.name: (pn.outline, list(pn.holes)) for pn in p.panels}


def edit_jacobian(design: Design, element_id: str, spacing: float | None = None) -> dict[str, PanelJacobian]:
    """Motion of every outline/hole polyline vertex per unit pointer motion,
    (k, 2, 2) per panel (see module doc for parameters: column 1 zero)."""
    if element_id.startswith("pt:"):
        moves = _moved_points(design, element_id)
        names = {design.pieces[j].name for j, *_ in moves}
        if not any(st.panel in names and st.kind != "seam" for st in design.strokes):
            # the pieces' panels are their outlines as given: exact, no drafting (a
            # FreeSewing piece has dozens of corners, each a handle)
            out = {}
            for j, idx, w, A in moves:
                pc = design.pieces[j]
                exact = np.zeros((len(pc.outline), 2, 2))
                exact[idx] = w[:, None, None] * A[None]
                out[pc.name] = PanelJacobian(exact, [np.zeros((len(h), 2, 2)) for h in pc.holes])
            return out
    kw = {} if spacing is None else {"spacing": spacing}
    p0, ctx = draft_with_context(design, **kw)
    setter, q, G = _dofs(design, element_id, ctx)
    out = {
        pn.name: PanelJacobian(np.zeros((len(pn.outline), 2, 2)), [np.zeros((len(h), 2, 2)) for h in pn.holes])
        for pn in p0.panels
    }
    for k in range(len(q)):
        e = np.zeros(len(q))
        e[k] = FD_STEP
        plus = _stack(draft_with_context(setter(design, q + e), **kw)[0])
        minus = _stack(draft_with_context(setter(design, q - e), **kw)[0])
        for name, J in out.items():
            d_out = (plus[name][0] - minus[name][0]) / (2 * FD_STEP)
            J.outline += d_out[:, :, None] * G[k][None, None, :]
            for h in range(len(J.holes)):
                d_h = (plus[name][1][h] - minus[name][1][h]) / (2 * FD_STEP)
                J.holes[h] += d_h[:, :, None] * G[k][None, None, :]
    return out


def apply_edit(design: Design, element_id: str, dd) -> Design:
    """The design after moving ``element_id`` by pointer motion dd (2,) [m]
    (for ``param:`` elements dd[0] is the option change, and the new value is
    held to the option's [min, max]). Every edit commits through here: a 2D
    handle drag and a 3D tug of the drape alike."""
    dd = np.asarray(dd, float).reshape(2)
    ctx = None if element_id.startswith("pt:") else draft_with_context(design)[1]
    setter, q, G = _dofs(design, element_id, ctx)
    lo, hi = _bounds(design, element_id, len(q))
    new = setter(design, np.clip(q + G @ dd, lo, hi))
    if element_id.startswith("pt:"):
        _check_piece_outline(new, element_id)
    return new


def _check_piece_outline(design: Design, element: str) -> None:
    """Refuse a point move that leaves the piece's outline self-intersecting
    or turned inside out, naming the piece and the point."""
    _, piece, i = _piece_point(design, element)
    P = np.asarray(piece.outline, float)
    at = f"({P[i][0]:.3f}, {P[i][1]:.3f}) m"
    hits = self_intersections(P)
    if hits:
        a, b = hits[0]
        raise PatternError(
            element,
            f"moving point {i} of piece {piece.name!r} to {at} makes its outline self-intersect "
            f"(edges {a} and {b}); move it less far",
        )
    if signed_area(P) <= 0:
        raise PatternError(element, f"moving point {i} of piece {piece.name!r} to {at} turns its outline inside out")


def edit_elements(design: Design) -> list[str]:
    """Every draggable element id of a design."""
    _, ctx = draft_with_context(design)
    out = [f"param:{o.name}" for o in sloper_of(design).options if not o.integer]
    for st in design.strokes:
        if st.kind == "curve":
            out += [f"cv:{st.panel}:{st.params['segment']}:{i}" for i in range(len(st.params["points"]))]
    for d in ctx.darts.values():
        pre = "hole" if d.kind == "hole" else "dart"
        names = ["position", "radius"] if d.kind == "hole" else ["position", "width", "length"]
        out += [f"{pre}:{d.id}:{n}" for n in names]
    for pc in design.pieces:
        if len(set(pc.corners)) >= 2:  # one corner alone has nothing to anchor a move
            out += [f"pt:{pc.name}:{c}" for c in pc.corners]
    return out
