"""Compare the outputs of two recordings (golden vs actual).

Outputs are the topics the table in schemas.topics marks as compared
(meshes, drapes, solve results). A message is
matched to its counterpart by (topic, generation, mesh_generation,
request_id, edit_id); when a key occurs several times (progress
publications), the last one counts. Float arrays and float scalars pass
when ``|actual - golden| <= atol + rtol * |golden|`` element-wise (NaN equals
NaN); integers, strings and shapes must match exactly. Fields that measure
time or ordering (``seq``, ``stamp_ns``, ``wall_time_s``) are not compared.
A fine mesh's prolongation (``fine_parent_tri``, ``fine_bary``) is compared
as the points it names on its coarse mesh (the same generation's, on each
side), not as triangle indices: a fine vertex on an edge or a vertex that
coarse triangles share may name either of them, and which one is round-off
(two CPUs gave coarse triangle 10 and 30 for one vertex, the same point to
4e-15 m).

Each side is a recording file read with its numbered parts (a recorder
restarted mid-session, couture.recording.parts) or a list of files. Payloads
the recorder set apart as rejected are not compared, only counted in the
report; an invalid payload among the valid traffic (a recording made before
the recorder checked) is a failure.

With a :class:`PhysicsRule` (what ``couture golden`` uses) drapes are
compared as physics, not as solver paths: two converged drapes agree within
what their residuals allow, iterations and wall times are only reported
(:func:`compare_drape`); fields a rule names as path-dependent elsewhere (a
mesh's ``x0``, the previous drape the remesher carried over) are held to the
rule's hard cap only (or, when larger, to the deviation of a drape of that
level accepted before as a separate equilibrium: that drape is what it carries).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable

import msgspec
import numpy as np

from couture.recording.mcapio import read_session
from couture.recording.parts import PathLike, describe, resolve
from schemas import topics as topic_table
from schemas.arrays import FLOAT_DTYPES, Array
from schemas.messages import DrapeMsg, MeshMsg, Message, SchemaError, decode

IGNORED_FIELDS = {"seq", "stamp_ns", "wall_time_s"}


@dataclass
class PhysicsRule:
    """Drapes compared as physics, not paths (STYLE.md "Compare physics, not paths").

    A drape converged to relative residual r (||R_free|| / ||F_g||) lies, to
    first order, within r ||F_g|| / lambda_min of the equilibrium (||dx||_2 <=
    ||K^-1|| ||R||, lambda_min the smallest eigenvalue of the free Hessian
    there). Two converged drapes of the same design are then within
    ``(r_golden + r_actual) * compliance``, compliance = ||F_g|| / lambda_min
    [m] measured on the golden drape (``compliance(key, golden) -> m``). The
    estimate is first order, and a soft drape is not linear over centimetres
    (measured: a coarse drape, SuperLU vs PARDISO, 1.5x the estimate), so
    the bound on the worst vertex is ``floor_m + safety * estimate``, at most
    the level's cap (a near-free mode, lambda_min -> 0, would allow anything)."""

    tol: dict[str, float]
    """level -> relative residual tolerance the solver node converges to; a
    converged drape above it fails (on either side)"""
    cap_m: dict[str, float]
    """level -> [m] never allowed, whatever residuals and compliance say"""
    floor_m: float = 1e-4
    """[m] always allowed: float32 positions (~30 nm here) and round-off in the solve"""
    safety: float = 2.0
    """factor on the first-order estimate (nonlinearity)"""
    compliance: Callable[[str, DrapeMsg], float] | None = None
    """match key, golden drape -> ||F_g|| / lambda_min [m]; None: the cap decides"""
    polish: Callable[[str, DrapeMsg, str], tuple[np.ndarray, float, Any] | None] | None = None
    """match key, drape, side ('golden' | 'actual') -> (x, relative residual, model) of
    that drape carried further towards its equilibrium on its own recording's model
    (couture.recording.golden.polisher), None where it cannot be; both sides polished
    are compared instead of the drapes as recorded. Where they lie farther apart
    than the bound, each is put into the other side's model: if both balance there
    (relative residual <= ``cross_tol``), the two are separate equilibria of the
    same physics (a bistable fold; measured: a frictionless skirt's hem, 1.5 mm
    apart, both at 5e-10), which passes and is reported; a changed physics does not
    balance the other side's model."""
    cross_tol: float = 1e-6
    """see ``polish``"""
    path_fields: dict[str, set[str]] = field(default_factory=dict)
    """topic -> float fields that carry solver state (held to the level's cap only)"""
    labels: set[str] = field(default_factory=set)
    """fields a session chooses afresh (``design_id``, a uuid per publish): not
    compared when two separately made recordings meet (``couture golden make``)"""

    def cap(self, level: str) -> float:
        return self.cap_m.get(level, max(self.cap_m.values(), default=math.inf))

    def bound(
        self, key: str, golden: DrapeMsg, actual: DrapeMsg, residuals: tuple[float, float] | None = None
    ) -> tuple[float, float]:
        """(bound [m], compliance [m]) for this pair of drapes (``residuals``: of their
        polished states, instead of the recorded ones)."""
        c = self.compliance(key, golden) if self.compliance is not None else math.inf
        rg, ra = residuals if residuals is not None else (golden.residual, actual.residual)
        r = _finite(rg) + _finite(ra)
        b = self.floor_m + self.safety * r * c if math.isfinite(c) else math.inf
        return min(self.cap(golden.level), b), c


def _balance(model: Any, x: np.ndarray) -> float:
    """Relative residual of ``x`` in ``model`` with friction anchored where x rests."""
    update = getattr(model, "update_friction", None)
    if update is not None:
        model.release_friction()
        update(x)
    return float(model.relative_residual(x))


def _finite(v: float) -> float:
    return v if math.isfinite(v) else math.inf


@dataclass
class DrapeRow:
    """One final drape, golden vs actual: what was compared and what was only reported."""

    key: str
    level: str
    generation: int
    converged: tuple[bool, bool]
    """golden, actual"""
    residual: tuple[float, float]
    tol: float
    iterations: tuple[int, int]
    """reported, never compared"""
    wall_time_s: tuple[float, float]
    """reported, never compared"""
    worst_vertex: int = -1
    deviation_m: float = 0.0
    """[m] largest |x_actual - x_golden| over vertices (the worst vertex's)"""
    bound_m: float = math.inf
    compliance_m: float = math.inf
    """||F_g|| / lambda_min of the golden drape [m]"""
    cross_residual: tuple[float, float] | None = None
    """relative residuals of the actual's state in the golden's model and back (PhysicsRule.polish)"""
    note: str = ""
    ok: bool = True


@dataclass
class TopicReport:
    topic: str
    matched: int = 0
    missing: list[str] = field(default_factory=list)
    """keys present in golden, absent in actual"""
    extra: list[str] = field(default_factory=list)
    """keys present in actual only (reported, not a failure)"""
    worst_abs: float = 0.0
    """largest |actual - golden| over float fields [field unit]"""
    worst_rel: float = 0.0
    """largest |actual - golden| / |golden| over float fields"""
    worst_where: str = ""
    failures: list[str] = field(default_factory=list)
    drapes: list[DrapeRow] = field(default_factory=list)
    """with a PhysicsRule: one row per final drape"""

    @property
    def ok(self) -> bool:
        return not self.missing and not self.failures


@dataclass
class CompareReport:
    golden: str
    actual: str
    rtol: float
    atol: float
    topics: dict[str, TopicReport] = field(default_factory=dict)
    first_deviation: str = ""
    rule: str = ""
    """the drape rule in words, '' when drapes were compared field by field"""
    rejected: dict[str, int] = field(default_factory=dict)
    """'golden' / 'actual' -> payloads the recorder set apart (not compared)"""

    @property
    def ok(self) -> bool:
        return bool(self.topics) and all(t.ok for t in self.topics.values()) and not self.first_deviation

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        d["ok"] = self.ok
        for name, t in self.topics.items():
            d["topics"][name]["ok"] = t.ok
        return d

    def text(self) -> str:
        lines = [
            f"compare {self.golden} -> {self.actual} (rtol={self.rtol:g}, atol={self.atol:g})",
            f"{'topic':<24} {'matched':>7} {'missing':>7} {'extra':>5} {'worst abs':>11} {'worst rel':>11}  status",
        ]
        for name, t in sorted(self.topics.items()):
            lines.append(
                f"{name:<24} {t.matched:>7} {len(t.missing):>7} {len(t.extra):>5} {t.worst_abs:>11.3e} "
                f"{t.worst_rel:>11.3e}  {'ok' if t.ok else 'FAIL'}" + (f"  ({t.worst_where})" if t.worst_where else "")
            )
        rows = [r for t in self.topics.values() for r in t.drapes]
        if rows:
            lines.append(f"drapes ({self.rule}); iterations and wall times reported, not compared:")
            lines.append(
                f"  {'drape':<14} {'gen':>3} {'status g/a':<11} {'residual g/a (tol)':<26} {'iters g/a':>9} "
                f"{'wall g/a [s]':>12} {'vertex':>6} {'dev [mm]':>8} {'bound':>7}"
            )
            for r in sorted(rows, key=lambda r: (r.generation, r.level)):
                st = "/".join("conv" if c else "stop" for c in r.converged)
                res = f"{r.residual[0]:.1e}/{r.residual[1]:.1e} ({r.tol:.0e})"
                its = f"{r.iterations[0]}/{r.iterations[1]}"
                wall = f"{r.wall_time_s[0]:.2f}/{r.wall_time_s[1]:.2f}"
                lines.append(
                    f"  drape/{r.level:<8} {r.generation:>3} {st:<11} {res:<26} {its:>9} {wall:>12} "
                    f"{r.worst_vertex:>6} {r.deviation_m * 1e3:>8.3f} {r.bound_m * 1e3:>7.3f}"
                    f"{'' if r.ok else '  FAIL'}"
                )
                if r.note:
                    lines.append(f"      {r.note}")
        if not self.topics:
            lines.append("(no output messages in the golden recording)")
        if any(self.rejected.values()):
            lines.append(
                "rejected payloads recorded apart (not compared): "
                + ", ".join(f"{side} {n}" for side, n in self.rejected.items())
            )
        if self.first_deviation:
            lines.append(f"first deviation: {self.first_deviation}")
        lines.append("PASS" if self.ok else "FAIL")
        return "\n".join(lines)


def _match_key(topic: str, msg: Message) -> str:
    parts = [topic, f"gen={msg.generation}"]
    for name in ("mesh_generation", "request_id", "edit_id"):
        v = getattr(msg, name, None)
        if v not in (None, "", 0):
            parts.append(f"{name}={v}")
    return " ".join(parts)


def _outputs(files: list[Path], topics: list[str]) -> tuple[dict[str, Message], dict[str, int], list[str], int]:
    """Last message per match key, the order keys first appeared (log time),
    bad payloads among the valid traffic, payloads recorded apart as rejected."""
    out: dict[str, Message] = {}
    order: dict[str, int] = {}
    bad: list[str] = []
    rejected = 0
    for rec in read_session(files, topics, which="all", parts=False):
        if rec.rejected:
            rejected += 1
            continue
        try:
            msg = decode(rec.data)
        except SchemaError as e:
            bad.append(f"{rec.topic}: {e}")
            continue
        k = _match_key(rec.topic, msg)
        out[k] = msg
        order.setdefault(k, rec.log_time)
    return out, order, bad, rejected


def compare(
    golden: PathLike | list[PathLike],
    actual: PathLike | list[PathLike],
    *,
    rtol: float = 1e-5,
    atol: float = 1e-8,
    topics: list[str] | None = None,
    rule: PhysicsRule | None = None,
) -> CompareReport:
    """Compare output messages of two recordings (see module doc); ``topics``
    defaults to the compared topics of the table. With ``rule``, final drapes
    are compared by :func:`compare_drape` and ``rtol``/``atol`` apply to the
    other fields and topics."""
    topics = topics or topic_table.compared_topics()
    g_files, a_files = resolve(golden), resolve(actual)
    rep = CompareReport(golden=describe(g_files), actual=describe(a_files), rtol=rtol, atol=atol)
    if rule is not None:
        caps = ", ".join(f"{lv} {c * 1e3:g} mm" for lv, c in rule.cap_m.items())
        rep.rule = (
            f"converged alike, residual <= tol on both sides, worst vertex <= {rule.floor_m * 1e3:g} mm + "
            f"{rule.safety:g} (r_golden + r_actual) ||F_g||/lambda_min, at most {caps}"
        )
    g, g_order, g_bad, rep.rejected["golden"] = _outputs(g_files, topics)
    a, _, a_bad, rep.rejected["actual"] = _outputs(a_files, topics)
    if g_bad:
        rep.first_deviation = f"golden holds an invalid message: {g_bad[0]}"
    firsts: list[tuple[int, str]] = []
    carried: dict[str, float] = {}
    """per level, the largest deviation [m] of a final drape accepted so far as a
    separate equilibrium: the next mesh's ``x0`` carries that drape over"""
    for k in sorted(g, key=lambda k: g_order[k]):
        topic = k.split(" ", 1)[0]
        tr = rep.topics.setdefault(topic, TopicReport(topic))
        if k not in a:
            tr.missing.append(k)
            firsts.append((g_order[k], f"{k}: missing in actual"))
            continue
        tr.matched += 1
        devs: list[str] = []
        gm, am = g[k], a[k]
        if rule is not None and isinstance(gm, DrapeMsg) and isinstance(am, DrapeMsg) and gm.level != "predicted":
            devs = compare_drape(k, gm, am, rule, tr)
            row = tr.drapes[-1] if tr.drapes else None
            if not devs and row is not None and row.key == k and row.note.startswith("separate equilibria"):
                carried[gm.level] = max(carried.get(gm.level, 0.0), row.deviation_m)
        else:
            skip = rule.path_fields.get(topic, set()) if rule is not None else set()
            level = topic.rsplit("/", 1)[-1]
            # a carried-over field (x0: the previous drape) may be as far off as that
            # drape was accepted to be
            cap = max(rule.cap(level), carried.get(level, 0.0)) if rule is not None else math.inf
            ignore = IGNORED_FIELDS | (rule.labels if rule is not None else set())
            points = _prolongation_points(gm, g), _prolongation_points(am, a)
            if points[0] is not None and points[1] is not None:
                ignore = ignore | PROLONGATION_FIELDS
                _compare_points(points[0], points[1], rtol, atol, tr, k, devs)
            _compare_values(g[k], a[k], "$", rtol, atol, tr, k, devs, skip=skip, cap=cap, ignore=ignore)
        if devs:
            tr.failures.extend(f"{k}: {d}" for d in devs)
            firsts.append((g_order[k], f"{k}: {devs[0]}"))
    for k in a:
        if k not in g:
            topic = k.split(" ", 1)[0]
            rep.topics.setdefault(topic, TopicReport(topic)).extra.append(k)
    for b in a_bad:
        rep.topics.setdefault("(invalid)", TopicReport("(invalid)")).failures.append(b)
        firsts.append((0, f"actual holds an invalid message: {b}"))
    if firsts and not rep.first_deviation:
        rep.first_deviation = min(firsts, key=lambda f: f[0])[1]
    return rep


PROLONGATION_FIELDS = {"fine_parent_tri", "fine_bary"}
"""a fine mesh's map onto its coarse mesh: compared as points (module doc)"""


def _prolongation_points(msg: Message, side: dict[str, Message]) -> np.ndarray | None:
    """The rest-space points [m] a fine mesh's prolongation names on the coarse
    mesh of its generation in the same recording, (n, 2); None when the message
    has no prolongation or that coarse mesh is not one message of this side with
    the triangles it names (the fields are then compared as they are)."""
    parent, bary = getattr(msg, "fine_parent_tri", None), getattr(msg, "fine_bary", None)
    if parent is None or bary is None:
        return None
    head = f"mesh/coarse gen={msg.generation}"
    coarse = [m for key, m in side.items() if (key == head or key.startswith(head + " ")) and isinstance(m, MeshMsg)]
    if len(coarse) != 1 or not isinstance(coarse[0], MeshMsg):
        return None
    tris, X = coarse[0].tris.numpy(), coarse[0].X.numpy().astype(np.float64)
    par, w = parent.numpy(), bary.numpy().astype(np.float64)
    if w.ndim != 2 or w.shape != (len(par), 3) or (len(par) and (par.min() < 0 or par.max() >= len(tris))):
        return None
    return np.einsum("nk,nkd->nd", w, X[tris[par]])


def _compare_points(
    pg: np.ndarray, pa: np.ndarray, rtol: float, atol: float, tr: TopicReport, key: str, devs: list[str]
) -> None:
    """The prolongations' points, golden ``pg`` and actual ``pa``, within ``atol + rtol |golden|``."""
    path = "$.fine_parent_tri/fine_bary"
    if pg.shape != pa.shape:
        devs.append(f"{path}: {len(pa)} points != golden {len(pg)}")
        return
    if not pg.size:
        return
    diff = np.linalg.norm(pa - pg, axis=1)
    i = int(np.argmax(diff))
    scale = np.linalg.norm(pg, axis=1)
    _note(tr, float(diff[i]), float(diff[i] / max(scale[i], 1e-12)), f"{key} {path}[{i}]")
    bad = ~(diff <= atol + rtol * scale)
    if bad.any():
        j = int(np.flatnonzero(bad)[0])
        devs.append(
            f"{path}[{j}]: the point on the coarse mesh {pa[j].tolist()} vs golden {pg[j].tolist()} "
            f"(|diff| {diff[j]:.3e} > {atol:g} + {rtol:g}*|golden|; {int(bad.sum())} vertices off)"
        )


def compare_drape(key: str, g: DrapeMsg, a: DrapeMsg, rule: PhysicsRule, tr: TopicReport) -> list[str]:
    """Physics, not paths: the same convergence status; a converged drape's
    residual within the level's tolerance on both sides; every vertex within
    ``rule.bound``. Iterations and wall times go into the report's row only.
    Returns the deviations (each names topic, generation and worst vertex)."""
    where = f"{key.split(' ', 1)[0]} generation {g.generation}"
    tol = rule.tol.get(g.level, math.inf)
    row = DrapeRow(
        key=key,
        level=g.level,
        generation=g.generation,
        converged=(g.converged, a.converged),
        residual=(g.residual, a.residual),
        tol=tol,
        iterations=(g.iterations, a.iterations),
        wall_time_s=(g.wall_time_s, a.wall_time_s),
    )
    tr.drapes.append(row)
    devs: list[str] = []
    if g.converged != a.converged:
        devs.append(
            f"{where}: {'converged' if a.converged else 'stopped (' + a.diagnosis + ')'} vs golden "
            f"{'converged' if g.converged else 'stopped (' + g.diagnosis + ')'}"
        )
    for side, m in (("golden", g), ("actual", a)):
        if m.converged and not m.residual <= tol:
            devs.append(f"{where}: {side} says converged at residual {m.residual:.3e} > tol {tol:.0e}")
    gx, ax = g.x.numpy().astype(np.float64), a.x.numpy().astype(np.float64)
    residuals = None
    models = None
    if g.converged and a.converged and rule.polish is not None and gx.shape == ax.shape:
        pg, pa = rule.polish(key, g, "golden"), rule.polish(key, a, "actual")
        if pg is not None and pa is not None:
            (gx, rg, gmod), (ax, ra, amod) = pg, pa
            residuals, models = (rg, ra), (gmod, amod)
    if gx.shape != ax.shape:
        devs.append(f"{where}: x shape {ax.shape} != golden {gx.shape}")
    else:
        dist = np.linalg.norm(ax - gx, axis=1) if gx.size else np.zeros(0)
        dist[~np.isfinite(dist)] = np.inf
        if dist.size:
            i = int(np.argmax(dist))
            row.worst_vertex, row.deviation_m = i, float(dist[i])
            _note(tr, row.deviation_m, 0.0, f"{where} vertex {i}")
        if g.converged and a.converged:
            row.bound_m, row.compliance_m = rule.bound(key, g, a, residuals)
            rg, ra = residuals if residuals is not None else (g.residual, a.residual)
            why = (
                f"{rule.floor_m * 1e3:g} mm + {rule.safety:g} x ({rg:.2e} + {ra:.2e}) x "
                f"{row.compliance_m:.3g} m, cap {rule.cap(g.level) * 1e3:g} mm"
                + (", both polished" if residuals is not None else "")
            )
        else:  # a stopped solve's state is wherever its path ended: only the cap holds
            row.bound_m = rule.cap(g.level)
            why = f"cap {row.bound_m * 1e3:g} mm (not both converged)"
        if row.deviation_m > row.bound_m and models is not None:
            # another equilibrium of the same physics? each state balanced by the other's model
            cross = (_balance(models[0], ax), _balance(models[1], gx))
            row.cross_residual = cross
            if max(cross) <= rule.cross_tol:
                row.note = (
                    f"separate equilibria of the same physics: worst vertex {row.worst_vertex} "
                    f"{row.deviation_m * 1e3:.3f} mm apart, each balances the other's model "
                    f"(residuals {cross[0]:.1e}, {cross[1]:.1e} <= {rule.cross_tol:g})"
                )
                row.bound_m = max(row.bound_m, row.deviation_m)
        if row.deviation_m > row.bound_m:
            devs.append(
                f"{where}: worst vertex {row.worst_vertex} deviates {row.deviation_m * 1e3:.3f} mm > bound "
                f"{row.bound_m * 1e3:.3f} mm ({why}); {int((dist > row.bound_m).sum())} vertices off"
            )
    row.ok = not devs
    return devs


def _compare_values(
    gv: Any,
    av: Any,
    path: str,
    rtol: float,
    atol: float,
    tr: TopicReport,
    key: str,
    devs: list[str],
    skip: set[str] = frozenset(),  # type: ignore[assignment]
    cap: float = math.inf,
    ignore: set[str] = IGNORED_FIELDS,
) -> None:
    if isinstance(gv, msgspec.Struct) and not isinstance(gv, Array):
        if type(gv) is not type(av):
            devs.append(f"{path}: type {type(av).__name__} != {type(gv).__name__}")
            return
        for name in gv.__struct_fields__:
            if name in ignore:
                continue
            if name in skip:  # solver state carried along: only the cap holds
                _compare_values(getattr(gv, name), getattr(av, name), f"{path}.{name}", 0.0, cap, tr, key, devs)
                continue
            _compare_values(getattr(gv, name), getattr(av, name), f"{path}.{name}", rtol, atol, tr, key, devs)
        return
    if isinstance(gv, Array) or isinstance(av, Array):
        if not (isinstance(gv, Array) and isinstance(av, Array)):
            devs.append(
                f"{path}: {'array' if isinstance(gv, Array) else gv!r} in golden, {'array' if isinstance(av, Array) else av!r} in actual"
            )
            return
        if list(gv.shape) != list(av.shape):
            devs.append(f"{path}: shape {tuple(av.shape)} != golden {tuple(gv.shape)}")
            return
        ga, aa = gv.numpy(), av.numpy()
        if gv.dtype in FLOAT_DTYPES or av.dtype in FLOAT_DTYPES:
            ga64, aa64 = ga.astype(np.float64), aa.astype(np.float64)
            diff = np.abs(aa64 - ga64)
            both_nan = np.isnan(ga64) & np.isnan(aa64)
            diff[both_nan] = 0.0
            diff[np.isnan(diff)] = np.inf
            if diff.size:
                i = int(np.argmax(diff))
                _note(
                    tr,
                    float(diff.flat[i]),
                    float(diff.flat[i] / max(abs(ga64.flat[i]), 1e-12)),
                    f"{key} {path}[{np.unravel_index(i, ga.shape)}]",
                )
                bad = diff > atol + rtol * np.abs(ga64)
                if bad.any():
                    j = int(np.flatnonzero(bad)[0])
                    idx = np.unravel_index(j, ga.shape)
                    devs.append(
                        f"{path}{list(idx)}: {aa64.flat[j]!r} vs golden {ga64.flat[j]!r} "
                        f"(|diff| {diff.flat[j]:.3e} > {atol:g} + {rtol:g}*|golden|; {int(bad.sum())} elements off)"
                    )
        elif not np.array_equal(ga, aa):
            j = int(np.flatnonzero(ga.ravel() != aa.ravel())[0])
            devs.append(
                f"{path}[{list(np.unravel_index(j, ga.shape))}]: {aa.flat[j]} vs golden {ga.flat[j]} (integers must match)"
            )
        return
    if isinstance(gv, float) or isinstance(av, float):
        if isinstance(gv, (int, float)) and isinstance(av, (int, float)) and not isinstance(gv, bool):
            if math.isnan(gv) and math.isnan(av):
                return
            d = abs(av - gv)
            _note(tr, d, d / max(abs(gv), 1e-12), f"{key} {path}")
            if not d <= atol + rtol * abs(gv):
                devs.append(f"{path}: {av!r} vs golden {gv!r}")
            return
    if isinstance(gv, list) and isinstance(av, list) and len(gv) == len(av):
        for i, (x, y) in enumerate(zip(gv, av, strict=True)):
            _compare_values(x, y, f"{path}[{i}]", rtol, atol, tr, key, devs)
        return
    if isinstance(gv, dict) and isinstance(av, dict) and gv.keys() == av.keys():
        for kk in gv:
            _compare_values(gv[kk], av[kk], f"{path}.{kk}", rtol, atol, tr, key, devs)
        return
    if gv != av:
        devs.append(f"{path}: {av!r} vs golden {gv!r}")


def _note(tr: TopicReport, abs_dev: float, rel_dev: float, where: str) -> None:
    if abs_dev > tr.worst_abs:
        tr.worst_abs, tr.worst_where = abs_dev, where
    tr.worst_rel = max(tr.worst_rel, rel_dev)


def write_json(report: CompareReport, path: str) -> None:
    from couture.jsonout import dumps  # standard JSON: an infinite deviation is written as null

    with open(path, "w") as f:
        f.write(dumps(report.to_json(), indent=2, default=str))
