"""Compare the outputs of two recordings (golden vs actual).

Outputs are the topics the table in schemas.topics marks as compared
(meshes, drapes, solve results). A message is
matched to its counterpart by (topic, generation, mesh_generation,
request_id, edit_id); when a key occurs several times (progress
publications), the last one counts. Float arrays and float scalars pass
when ``|actual - golden| <= atol + rtol * |golden|`` element-wise (NaN equals
NaN); integers, strings and shapes must match exactly. Fields that measure
time or ordering (``seq``, ``stamp_ns``, ``wall_time_s``) are not compared.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from typing import Any

import msgspec
import numpy as np

from couture.recording.mcapio import read_session
from schemas import topics as topic_table
from schemas.arrays import FLOAT_DTYPES, Array
from schemas.messages import Message, SchemaError, decode

IGNORED_FIELDS = {"seq", "stamp_ns", "wall_time_s"}


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
        lines = [f"compare {self.golden} -> {self.actual} (rtol={self.rtol:g}, atol={self.atol:g})",
                 f"{'topic':<24} {'matched':>7} {'missing':>7} {'extra':>5} {'worst abs':>11} {'worst rel':>11}  status"]
        for name, t in sorted(self.topics.items()):
            lines.append(f"{name:<24} {t.matched:>7} {len(t.missing):>7} {len(t.extra):>5} {t.worst_abs:>11.3e} "
                         f"{t.worst_rel:>11.3e}  {'ok' if t.ok else 'FAIL'}" + (f"  ({t.worst_where})" if t.worst_where else ""))
        if not self.topics:
            lines.append("(no output messages in the golden recording)")
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


def _outputs(path: str, topics: list[str]) -> tuple[dict[str, Message], dict[str, int], list[str]]:
    """Last message per match key, the order keys first appeared (log time), bad payloads."""
    out: dict[str, Message] = {}
    order: dict[str, int] = {}
    bad: list[str] = []
    for rec in read_session(path, topics):
        try:
            msg = decode(rec.data)
        except SchemaError as e:
            bad.append(f"{rec.topic}: {e}")
            continue
        k = _match_key(rec.topic, msg)
        out[k] = msg
        order.setdefault(k, rec.log_time)
    return out, order, bad


def compare(golden: str, actual: str, *, rtol: float = 1e-5, atol: float = 1e-8,
            topics: list[str] | None = None) -> CompareReport:
    """Compare output messages of two recordings (see module doc); ``topics``
    defaults to the compared topics of the table."""
    topics = topics or topic_table.compared_topics()
    rep = CompareReport(golden=golden, actual=actual, rtol=rtol, atol=atol)
    g, g_order, g_bad = _outputs(golden, topics)
    a, _, a_bad = _outputs(actual, topics)
    if g_bad:
        rep.first_deviation = f"golden holds an invalid message: {g_bad[0]}"
    firsts: list[tuple[int, str]] = []
    for k in sorted(g, key=lambda k: g_order[k]):
        topic = k.split(" ", 1)[0]
        tr = rep.topics.setdefault(topic, TopicReport(topic))
        if k not in a:
            tr.missing.append(k)
            firsts.append((g_order[k], f"{k}: missing in actual"))
            continue
        tr.matched += 1
        devs: list[str] = []
        _compare_values(g[k], a[k], "$", rtol, atol, tr, k, devs)
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


def _compare_values(gv: Any, av: Any, path: str, rtol: float, atol: float, tr: TopicReport, key: str, devs: list[str]) -> None:
    if isinstance(gv, msgspec.Struct) and not isinstance(gv, Array):
        if type(gv) is not type(av):
            devs.append(f"{path}: type {type(av).__name__} != {type(gv).__name__}")
            return
        for name in gv.__struct_fields__:
            if name in IGNORED_FIELDS:
                continue
            _compare_values(getattr(gv, name), getattr(av, name), f"{path}.{name}", rtol, atol, tr, key, devs)
        return
    if isinstance(gv, Array) or isinstance(av, Array):
        if not (isinstance(gv, Array) and isinstance(av, Array)):
            devs.append(f"{path}: {'array' if isinstance(gv, Array) else gv!r} in golden, {'array' if isinstance(av, Array) else av!r} in actual")
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
                _note(tr, float(diff.flat[i]), float(diff.flat[i] / max(abs(ga64.flat[i]), 1e-12)), f"{key} {path}[{np.unravel_index(i, ga.shape)}]")
                bad = diff > atol + rtol * np.abs(ga64)
                if bad.any():
                    j = int(np.flatnonzero(bad)[0])
                    idx = np.unravel_index(j, ga.shape)
                    devs.append(f"{path}{list(idx)}: {aa64.flat[j]!r} vs golden {ga64.flat[j]!r} "
                                f"(|diff| {diff.flat[j]:.3e} > {atol:g} + {rtol:g}*|golden|; {int(bad.sum())} elements off)")
        elif not np.array_equal(ga, aa):
            j = int(np.flatnonzero(ga.ravel() != aa.ravel())[0])
            devs.append(f"{path}[{list(np.unravel_index(j, ga.shape))}]: {aa.flat[j]} vs golden {ga.flat[j]} (integers must match)")
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
    with open(path, "w") as f:
        json.dump(report.to_json(), f, indent=2, default=str)
