"""Pattern tools on the pattern server's panel: add a curve point, draw a
dart, sew two segments, mark symmetry. A tool is armed by its button; the
next click(s) on the pattern make one stroke of couture.pattern, committed
as a new design. Unarmed, a click on the cloth picks the material point."""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Callable

import msgspec
import numpy as np
import viser

from couture.pattern.pieces import with_mirrored_curve
from couture.ui.geometry import MaterialPoint
from couture.ui.pattern_view import PatternView
from couture.ui.widgets import on_user_change
from schemas.design import Design, Stroke

IDLE_HELP = "Drag a handle to edit (click one to see its name); click the cloth to find it in 3D."
TOOL_HELP = {
    "curve": "**Curve point**: click the boundary where the new control point goes; then drag it.",
    "dart": "**Dart**: click the boundary where the dart goes.",
    "seam": "**Sew**: click the first segment, then the second.",
    "symmetry": "**Symmetry**: click the segment the panel is mirrored about.",
}

SegmentPick = tuple[str, str, float]
"""(panel, segment, fraction along the segment in [0, 1])"""


@dataclass
class ArmedTool:
    tool: str
    """'curve', 'dart', 'seam' or 'symmetry'"""
    picks: list[SegmentPick] = field(default_factory=list)


class PatternTools:
    """The "Tools" folder and what a click on the pattern does."""

    def __init__(
        self,
        gui: viser.GuiApi,
        view2d: PatternView,
        design: Callable[[], Design],
        commit: Callable[[Design], None],
        pick: Callable[[MaterialPoint], None],
    ):
        self.view2d, self.design, self.commit, self.pick = view2d, design, commit, pick
        self.armed: ArmedTool | None = None
        self._stroke_ids = itertools.count(1)
        with gui.add_folder("Tools"):
            self.help = gui.add_markdown(IDLE_HELP)
            for label, tool in (
                ("Add a curve point", "curve"),
                ("Draw a dart", "dart"),
                ("Sew two segments", "seam"),
                ("Mark symmetry", "symmetry"),
                ("Cancel tool", None),
            ):

                def arm(_: viser.GuiEvent, tool: str | None = tool) -> None:
                    self.arm(tool)

                gui.add_button(label).on_click(arm)
            self.show_mesh = gui.add_checkbox("show mesh", False)
            on_user_change(self.show_mesh, lambda: view2d.set_show_mesh(bool(self.show_mesh.value)))
            self.show_names = gui.add_checkbox("show all handle names", False)
            on_user_change(self.show_names, lambda: view2d.set_show_all_labels(bool(self.show_names.value)))

    def say(self, text: str) -> None:
        self.help.content = text

    def arm(self, tool: str | None) -> None:
        self.armed = None if tool is None else ArmedTool(tool)
        self.say(TOOL_HELP.get(tool or "", IDLE_HELP))

    def click(self, p: np.ndarray, panel: str | None) -> None:
        """A click on the pattern at ``p`` (display coordinates [m])."""
        if self.armed is None:
            mp = self.view2d.locate(p)
            if mp is not None:
                self.pick(mp)
            return
        seg = self.view2d.nearest_segment(p)
        if seg is None:
            return
        if self.armed.tool == "dart" and seg[0] in {pc.name for pc in self.design().pieces}:
            self.arm(None)
            self.say(f"**Dart**: {seg[0]} is an imported piece: its darts come with it (sewn leg to leg); none added.")
            return
        self.armed.picks.append(seg)
        picks = self.armed.picks
        if self.armed.tool == "seam" and len(picks) < 2:
            self.say(f"**Sew**: first is {picks[0][0]}:{picks[0][1]}; click the second segment.")
            return
        stroke = self._stroke(self.armed.tool, picks)
        d = self.design()
        strokes = [s for s in d.strokes if s.id != stroke.id] + [stroke]
        self.arm(None)
        new = msgspec.structs.replace(d, strokes=strokes)
        if stroke.kind == "curve":
            new = with_mirrored_curve(new, stroke.id)  # a 'Cut 2' twin's segment gets the mirror curve
        self.commit(new)

    def _stroke(self, tool: str, picks: list[SegmentPick]) -> Stroke:
        n = next(self._stroke_ids)
        pn, sn, t = picks[0]
        if tool == "curve":
            # couture.pattern's curve stroke: control points [s, dn] (fraction
            # along the segment, normal displacement [m]); a new point starts at dn = 0
            old = next(
                (
                    s
                    for s in self.design().strokes
                    if s.kind == "curve" and s.panel == pn and s.params.get("segment") == sn
                ),
                None,
            )
            pts = [list(q) for q in (old.params["points"] if old else [])]
            pts = sorted(pts + [[round(min(max(t, 0.02), 0.98), 4), 0.0]])
            return Stroke(
                id=old.id if old else f"curve-{pn}-{sn}", kind="curve", panel=pn, params={"segment": sn, "points": pts}
            )
        if tool == "dart":
            # couture.pattern's boundary dart: position along the segment (0..1), width, length [m]
            return Stroke(
                id=f"dart-{n}",
                kind="dart",
                panel=pn,
                params={"segment": sn, "position": round(min(max(t, 0.05), 0.95), 4), "width": 0.02, "length": 0.08},
            )
        if tool == "symmetry":
            return Stroke(id=f"symmetry-{n}", kind="symmetry", panel=pn, params={"axis": sn})
        (pa, sa, _), (pb, sb, _) = picks
        return Stroke(
            id=f"seam-{n}",
            kind="seam",
            panel="",
            params={"a_panel": pa, "a_segment": sa, "b_panel": pb, "b_segment": sb},
        )
