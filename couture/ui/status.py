"""Status text on the 3D server's panel: a design the nodes rejected (the
field and why), what is on screen and by which method, the nodes of the
session with their state and busiest rates, and the adapter's notes on what
the pipeline can do right now."""

from __future__ import annotations

import html
import json
import math
import threading
import time
from dataclasses import dataclass, field
from typing import Iterable

import viser

from couture.ui.state import DrapeFrame

NOISY_RATE_PREFIXES = ("sent/status", "recv/status")


@dataclass
class NodeInfo:
    name: str
    alive: bool = True
    kind: str = ""
    state: str = ""
    rates: dict[str, float] = field(default_factory=dict)
    last_error: str = ""
    seen: float = field(default_factory=time.time)


def useful_rates(rates: dict[str, float]) -> list[tuple[str, float]]:
    """A node's rates worth showing: not the status heartbeat's own traffic, busiest first."""
    keep = [(k, v) for k, v in rates.items() if not k.startswith(NOISY_RATE_PREFIXES) and v > 0]
    return sorted(keep, key=lambda kv: -kv[1])


def describe_frame(f: DrapeFrame) -> str:
    """Which method produced the drape on screen, in words."""
    if f.level == "predicted":
        if f.error_estimate_m is not None and math.isfinite(f.error_estimate_m):
            err = f"about {1e3 * f.error_estimate_m:.2g} mm from equilibrium (estimate)"
        elif f.error_estimate is None:
            err = "error estimate pending"
        else:
            err = f"error estimate {f.error_estimate:.2g}"
        return f"prediction ({f.method or '?'}), {err}, generation {f.generation}"
    who = f.solver or f.method or "solver"
    if f.solver and f.method and f.method not in f.solver:
        who += f" ({f.method})"
    res = "" if not math.isfinite(f.residual) else f", residual {f.residual:.2g}"
    if not f.final:
        state = "solving"
    elif f.converged:
        state = "converged"
    elif f.converged is None:
        state = "final"
    else:
        state = "not converged" + (f": {f.diagnosis}" if f.diagnosis else "")
    return f"{f.level} solve by {who}{res}, {state}, generation {f.generation}"


class StatusPanel:
    """The "Status" folder. Setters are thread-safe and only mark the text
    dirty; the render thread redraws it with :meth:`refresh`."""

    def __init__(self, gui: viser.GuiApi):
        with gui.add_folder("Status"):
            # the page's tests and benchmark read data-seq/data-tag/data-generation
            self.frame_html = gui.add_html('<div id="couture-frame" data-seq="0">on screen: nothing yet</div>')
            self.table = gui.add_markdown("| node | state | rates |\n|---|---|---|\n| (none) | | |")
        self.nodes: dict[str, NodeInfo] = {}
        self.notes: list[str] = []
        """extra lines from the bus adapter (e.g. predictions off)"""
        self.rejection = ""
        """why the newest design was rejected ('' when it was not), shown first"""
        self.dirty = threading.Event()

    def set_live_nodes(self, nodes: dict[str, bool] | Iterable[str]) -> None:
        """Liveliness: name -> alive (or the names alive now; others are dead).
        A dead node stays listed as dead."""
        alive = dict(nodes) if isinstance(nodes, dict) else {n: True for n in nodes}
        if not isinstance(nodes, dict):
            for n in self.nodes:
                alive.setdefault(n, False)
        for n, a in alive.items():
            info = self.nodes.setdefault(n, NodeInfo(n))
            info.alive = bool(a)
            if a:
                info.seen = time.time()
        self.dirty.set()

    def set_node_status(
        self, name: str, *, kind: str = "", state: str = "", rates: dict | None = None, last_error: str = ""
    ) -> None:
        info = self.nodes.setdefault(name, NodeInfo(name))
        info.kind, info.state, info.rates, info.last_error = kind, state, dict(rates or {}), last_error
        info.seen = time.time()
        self.dirty.set()

    def set_rejection(self, text: str) -> None:
        """A design a node rejected: who and why (the field, its value, the
        allowed range); '' clears it (a later design was meshed)."""
        if text != self.rejection:
            self.rejection = text
            self.dirty.set()

    def set_notes(self, notes: list[str]) -> None:
        if notes != self.notes:
            self.notes = list(notes)
            self.dirty.set()

    def live_solvers(self) -> list[str]:
        return sorted(n for n, i in self.nodes.items() if i.alive and (i.kind == "solver" or n.startswith("solver")))

    def show_frame(self, frame: DrapeFrame, seq: int) -> None:
        """The marker of the drape just pushed to the browser."""
        tag = html.escape(json.dumps(frame.tag)) if frame.tag is not None else ""
        self.frame_html.content = (
            f'<div id="couture-frame" data-seq="{seq}" data-tag="{tag}" '
            f'data-level="{frame.level}" data-generation="{frame.generation}" '
            f'style="font-size:12px">on screen: {html.escape(describe_frame(frame))}</div>'
        )

    def refresh(self, on_screen: DrapeFrame | None) -> None:
        rows = []
        if self.rejection:
            rows += [f"**Design rejected**: {_md_escape(self.rejection)}. The last good drape stays on screen.", ""]
        rows += ["| node | state | rates |", "|---|---|---|"]
        for n in sorted(self.nodes):
            info = self.nodes[n]
            state = (info.state or "alive") if info.alive else "**DEAD**"
            if info.alive and info.last_error:
                state += f" (last error: {info.last_error[:80]})"
            rates = ", ".join(f"{k} {v:.3g}/s" for k, v in useful_rates(info.rates)[:3])
            rows.append(f"| {n} | {state} | {rates} |")
        if len(rows) == 2:
            rows.append("| (none) | | |")
        if on_screen is not None:
            age = time.time() - on_screen.received
            rows += ["", f"**On screen**: {describe_frame(on_screen)}, {age:.1f} s old"]
        if self.notes:
            rows += [""] + [f"- {n}" for n in self.notes]
        self.table.content = "\n".join(rows)


def _md_escape(text: str) -> str:
    """Plain text inside Markdown: no table pipes, emphasis or markup taken from it
    (underscores stay: inside a word, as in field names, they emphasise nothing)."""
    for ch in "\\`*[]|<>":
        text = text.replace(ch, "\\" + ch)
    return text
