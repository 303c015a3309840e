"""The "Adjust pattern" folder and its 3D handle (Bartle 2016, ``couture.adjust``):
edit the drape directly, get the pattern that drapes that way.

Pick a loop, then drag its handle in the 3D view:

- ``hem``: the handle sits on the front of the hem and slides only
  vertically (up: shorter; down: longer, the drape continued below its hem
  along its own flare);
- ``waist``: the handle sits on the front of the garment at the mannequin's
  waist and slides only radially, away from the torso axis (out: looser);
  an offset d [m] is a girth change of 2πd.

The amount follows the handle (and can be typed). On release, when "adjust
on release" is on, or with the "Adjust pattern" button, ``on_request(edit,
amount)`` hands the request to the bus adapter, which sends it to the
adjust node; its progress (:meth:`AdjustPanel.show_status`) is shown under
the buttons, and at the end the verdict: whether the adjusted pattern met the
goal (Hausdorff, stretch, re-simulated patterns, seconds) and, if not, why. The adjusted design comes back as the new current design (as
any other publisher's design does); "Undo adjustment" puts back the design
before it (``on_undo(design)``, a new design like any edit).
"""

from __future__ import annotations

import math
import threading
from typing import Any, Callable

import numpy as np
import viser

from schemas.design import Design

LOOPS = ("hem", "waist")
MIN_AMOUNT_M = 0.005
"""[m] smaller requests are refused (nothing to adjust)"""
LOOP_BAND_M = 0.02
"""[m] vertices this close to the loop's height make the loop"""


def loop_anchor(x: np.ndarray, loop: str) -> tuple[np.ndarray, np.ndarray]:
    """Where a loop's handle sits on a drape ``x`` (n, 3) [m], and the unit
    direction it slides along: the hem's front-most lowest vertex, straight
    up; the front-most vertex at the mannequin's waist height, radially out
    from the torso axis. Raises ValueError when the garment has no such loop."""
    from couture.pattern.mannequin import TORSO_AXIS_Z, WAIST_Y

    x = np.asarray(x, np.float64)
    if x.ndim != 2 or x.shape[1] != 3 or not len(x):
        raise ValueError("no drape on screen: nothing to adjust")
    y = x[:, 1]
    if loop == "hem":
        near = np.flatnonzero(y <= y.min() + LOOP_BAND_M)
        v = near[np.argmax(x[near, 2])]
        return x[v].copy(), np.array([0.0, 1.0, 0.0])
    if loop == "waist":
        if not y.min() + LOOP_BAND_M < WAIST_Y < y.max() + LOOP_BAND_M:
            raise ValueError(
                f"the garment does not go round the waist (y = {WAIST_Y} m): it spans {y.min():.2f}..{y.max():.2f} m"
            )
        near = np.flatnonzero(np.abs(y - WAIST_Y) <= LOOP_BAND_M)
        if not len(near):
            near = np.array([int(np.argmin(np.abs(y - WAIST_Y)))])
        v = near[np.argmax(x[near, 2])]
        r = np.array([x[v, 0], 0.0, x[v, 2] - TORSO_AXIS_Z])
        n = np.linalg.norm(r)
        return x[v].copy(), (r / n if n > 1e-9 else np.array([0.0, 0.0, 1.0]))
    raise ValueError(f"loop {loop!r}: choose one of {LOOPS}")


def amount_of(loop: str, offset: np.ndarray, direction: np.ndarray) -> float:
    """The request's amount [m] for a handle moved by ``offset`` from its
    anchor: hem: the length change (up is shorter: negative); waist: the
    girth change 2π d for a radial offset d."""
    d = float(np.dot(offset, direction))
    return -d if loop == "hem" else 2.0 * math.pi * d


def _wxyz_x_to(u: np.ndarray) -> tuple[float, float, float, float]:
    """The turn about +y that takes the handle's local x axis to the horizontal ``u``."""
    th = math.atan2(-float(u[2]), float(u[0]))
    return (math.cos(th / 2), 0.0, math.sin(th / 2), 0.0)


class AdjustPanel:
    def __init__(
        self,
        server: viser.ViserServer,
        on_request: Callable[[str, float], None],
        on_undo: Callable[[Design], None],
        drape: Callable[[], Any] = lambda: None,
        design: Callable[[], Design | None] = lambda: None,
    ):
        """``drape()``: the positions on screen (n, 3) or None; ``design()``: the design shown."""
        self.server, self.on_request, self.on_undo = server, on_request, on_undo
        self.drape, self.design = drape, design
        self._lock = threading.Lock()
        self.anchor: np.ndarray | None = None
        self.direction = np.array([0.0, 1.0, 0.0])
        self.dragging = False
        self.before: Design | None = None
        """the design shown when the last request went out (what undo restores)"""
        self.request_id = ""
        gui = server.gui
        with gui.add_folder("Adjust pattern", expand_by_default=False):
            self.help = gui.add_markdown(
                "Drag the loop's handle in the 3D view (hem: up = shorter, down = longer; waist: out = looser); "
                "on release the pattern is adjusted so that it drapes that way."
            )
            self.loop = gui.add_dropdown("loop", LOOPS, initial_value="hem")
            self.amount_cm = gui.add_number("change [cm]", 0.0, min=-100.0, max=100.0, step=0.5)
            self.on_release = gui.add_checkbox("adjust on release", True)
            self.button = gui.add_button("Adjust pattern")
            self.undo = gui.add_button("Undo adjustment", disabled=True)
            self.progress = gui.add_markdown("")
        self.handle = server.scene.add_transform_controls(
            "/adjust/handle",
            scale=0.12,
            active_axes=(True, False, False),
            disable_sliders=True,
            disable_rotations=True,
            depth_test=False,
            visible=False,
        )

        def on_loop(_: Any) -> None:
            self.place()

        def on_button(_: Any) -> None:
            self.request()

        def on_undo_button(_: Any) -> None:
            self.undo_last()

        self.loop.on_update(on_loop)
        self.button.on_click(on_button)
        self.undo.on_click(on_undo_button)

        # async: viser runs it on its event loop, so the phases arrive in order
        # (start, updates, end); the request it may send is one publish
        async def on_handle(event: Any) -> None:
            {"start": self._drag_start, "end": self._released}.get(event.phase, self._moved)()

        self.handle.on_update(on_handle)

    # -- the handle
    def place(self) -> bool:
        """Put the handle on the chosen loop of the drape on screen (hidden when there is none)."""
        x = self.drape()
        if x is None:
            return False
        try:
            p, u = loop_anchor(x, str(self.loop.value))
        except ValueError as e:
            self.handle.visible = False
            self.help.content = f"**{self.loop.value}**: {e}"
            return False
        with self._lock:
            self.anchor, self.direction = p, u
        # the handle's local x axis is the one it slides along
        self.handle.wxyz = _wxyz_x_to(u) if self.loop.value == "waist" else (math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5))
        self.handle.position = tuple(p)
        self.handle.visible = True
        return True

    def follow(self, x: np.ndarray) -> None:
        """A new drape on screen: the handle follows its loop (not while dragged)."""
        if self.dragging:
            return
        try:
            p, _ = loop_anchor(x, str(self.loop.value))
        except ValueError:
            return
        if self.anchor is None or np.linalg.norm(p - self.anchor) > 0.005:
            self.place()

    def _drag_start(self) -> None:
        self.dragging = True
        if self.anchor is None:
            self.place()

    def _moved(self) -> None:
        if self.anchor is None:
            return
        off = np.asarray(self.handle.position, np.float64) - self.anchor
        self.amount_cm.value = round(100.0 * amount_of(str(self.loop.value), off, self.direction), 1)  # type: ignore[misc]  # viser has the setter; mypy misses it

    def _released(self) -> None:
        self.dragging = False
        self._moved()
        if self.on_release.value:
            self.request()

    # -- requests
    def request(self) -> tuple[str, float] | None:
        """Send the loop and amount shown (None: nothing sent, the text says why)."""
        loop, amount = str(self.loop.value), float(self.amount_cm.value) / 100.0
        why = ""
        if not math.isfinite(amount) or abs(amount) < MIN_AMOUNT_M:
            why = f"drag the {loop} handle (or type a change of at least {100 * MIN_AMOUNT_M:g} cm) first"
        if why:
            self.show_error(why)
            self.place()
            return None
        self.before = self.design()
        self.progress.content = f"sent: {loop} {100 * amount:+.1f} cm; waiting for the adjust node"
        try:
            self.on_request(loop, amount)
        except Exception as e:  # no adjust node, no design yet: say so, keep the design
            self.show_error(str(e))
            return None
        return loop, amount

    def show_status(self, state: str, iteration: int, text: str, error: str = "", goal_met: bool | None = None) -> None:
        """Progress of the request sent (the adjust node's ``adjust/status``);
        ``goal_met``: done's verdict against the goal (None: not judged), its
        figures and reasons at the end of ``text``."""
        if state == "failed":
            self.show_error(error or text)
            return
        verdict = "" if goal_met is None else (", **goal met**" if goal_met else ", **goal NOT met**")
        head = {"running": "adjusting", "iteration": f"iteration {iteration}", "done": f"**done**{verdict}"}.get(
            state, state
        )
        self.progress.content = f"{head}: {text}"
        if state == "done":
            self.amount_cm.value = 0.0  # type: ignore[misc]  # viser has the setter
            self.undo.disabled = self.before is None

    def show_error(self, text: str) -> None:
        self.progress.content = f"**adjustment failed, the design is unchanged**: {text}"
        self.amount_cm.value = 0.0  # type: ignore[misc]  # viser has the setter
        self.place()

    def undo_last(self) -> Design | None:
        """Put back the design shown before the last adjustment (a new design, published like any edit)."""
        before, self.before = self.before, None
        self.undo.disabled = True
        if before is None:
            return None
        self.progress.content = "undone: the design before the adjustment is back"
        self.on_undo(before)
        return before
