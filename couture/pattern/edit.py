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
from schemas.design import Design, Stroke

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


def _dofs(design: Design, element: str, ctx: DraftContext):
    """(setter, values q, G) for an element: q are the scalar values the element
    changes, G (len(q), 2) maps a pointer motion dd to dq; setter(design, q) -> Design.
    The setter takes any q (the Jacobian differences across an option's bound);
    :func:`_bounds` gives the range an edit may commit."""
    parts = element.split(":")
    kind = parts[0]
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
            return d

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
    raise PatternError(element, "unknown element id (expected param:, cv:, dart: or hole:)")


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
    _, ctx = draft_with_context(design)
    setter, q, G = _dofs(design, element_id, ctx)
    lo, hi = _bounds(design, element_id, len(q))
    return setter(design, np.clip(q + G @ dd, lo, hi))


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
    return out
