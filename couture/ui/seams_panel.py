"""The "Seams" folder of the pattern view: the design's seams with the
importer's confidence and reason, least sure first (``couture.pattern.seam_review``);
pick one and confirm it or drop it (its two segments then stay free). A thin
layer: the review's logic is bus-free in couture.pattern."""

from __future__ import annotations

import logging
from typing import Callable

import viser

from couture.pattern.errors import PatternError
from couture.pattern.seam_review import SeamRow, confirm_seam, drop_seam, seam_rows
from couture.ui.widgets import on_user_change
from schemas.design import Design

log = logging.getLogger("couture.ui")

NONE = "(no seams)"


class SeamsPanel:
    def __init__(self, gui: viser.GuiApi, design: Callable[[], Design], commit: Callable[[Design], None]):
        self.design, self.commit = design, commit
        self.rows: list[SeamRow] = []
        self._ids: dict[str, str] = {}
        """dropdown choice -> seam stroke id"""
        with gui.add_folder("Seams", expand_by_default=False):
            self.table = gui.add_markdown("")
            self.choice = gui.add_dropdown("seam", (NONE,))
            self.confirm_button = gui.add_button("Confirm seam")
            self.drop_button = gui.add_button("Drop seam")
            self.note = gui.add_markdown("")
        self.confirm_button.on_click(lambda _: self.act("confirm"))
        self.drop_button.on_click(lambda _: self.act("drop"))
        on_user_change(self.choice, lambda: self.say(""))

    def say(self, text: str) -> None:
        self.note.content = text

    def show(self, design: Design) -> None:
        """List the seams of ``design`` (the choice kept when that seam still exists)."""
        self.rows = seam_rows(design)
        keep = self._ids.get(str(self.choice.value))
        self._ids = {f"{i + 1}. {r.label}": r.stroke_id for i, r in enumerate(self.rows)}
        options = tuple(self._ids) or (NONE,)
        if tuple(self.choice.options) != options:
            self.choice.options = options
        chosen = next((c for c, sid in self._ids.items() if sid == keep), options[0])
        if self.choice.value != chosen:
            self.choice.value = chosen  # type: ignore[misc]  # viser has the setter; mypy misses it
        suggested = [r for r in self.rows if r.confidence is not None and not r.confirmed]
        lines = [
            f"{len(self.rows)} seams; {len(suggested)} suggested by the importer, to confirm or drop (least sure first)."
            if self.rows
            else "No seams: sew two segments with the tool above."
        ]
        if self.rows:
            lines += ["", "| seam | confidence |", "|---|---|"]
            for r in self.rows:
                how = (
                    "confirmed"
                    if r.confirmed
                    else ("drawn" if r.confidence is None else f"{r.confidence:.2f} {r.reason}")
                )
                lines.append(f"| {r.a} + {r.b} | {how} |")
        self.table.content = "\n".join(lines)

    def act(self, what: str) -> None:
        """Confirm or drop the chosen seam: a new design, committed."""
        sid = self._ids.get(str(self.choice.value))
        if sid is None:
            self.say("No seam chosen.")
            return
        try:
            new = (confirm_seam if what == "confirm" else drop_seam)(self.design(), sid)
        except PatternError as e:
            self.say(f"**{what}**: {e}")
            return
        self.say(f"{'Confirmed' if what == 'confirm' else 'Dropped'} {sid}.")
        self.commit(new)
