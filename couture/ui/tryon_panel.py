"""The "Try-on" folder on the 3D server's panel (Meng 2010 §6, couture.tryon):
pick a panel, then move it, turn it, drag it around or up and down the body,
fix or release it; sew the next seam or unsew the last; start sequential
sewing with no seam sewn. A click on the body in the 3D view picks a point
(its ray against the body's ellipsoid proxy, couture.ui.geometry.pick_body);
"Drag to picked point" then slides the panel around and along the body until
its centroid is at that point's azimuth and height; "Drag to arrangement point"
does the same for the named body landmark chosen in the "arrangement point"
list (couture.pattern.landmarks: 'front_waist', 'back_neck', ..., measured on
the body shown; a design file places a piece there before any drape with
``placement.ring = 'point'``). Each button hands one op (the fields of a
``couture/tryon/v1`` message) to ``on_op``; the solver applies it to its
drape and re-solves."""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np
import viser

NO_PANEL = "(none)"
NO_POINT = "(none)"

TryOnOp = dict[str, Any]
"""op, panel, vector [m or axis], angle [rad], seam, sewn (TryOnMsg's fields)"""


class TryOnPanel:
    def __init__(
        self,
        gui: viser.GuiApi,
        on_op: Callable[[TryOnOp], None],
        drape: Callable[[], tuple[Any, Any]] = lambda: (None, None),
        body: Callable[[], str] = lambda: "default",
    ):
        """``drape()``: (mesh, x) on screen, for a panel's outward direction;
        ``body()``: the body shown (its arrangement points)."""
        from couture.pattern.landmarks import point_names

        self.on_op, self.drape, self.body = on_op, drape, body
        self.target = None
        """the BodyPick a click on the body made (couture.ui.geometry), or None"""
        with gui.add_folder("Try-on", expand_by_default=False):
            self.help = gui.add_markdown("Pick a panel; each button re-drapes from the current drape.")
            self.panel = gui.add_dropdown("panel", (NO_PANEL,), initial_value=NO_PANEL)
            self.step_cm = gui.add_number("step [cm]", 2.0, min=0.1, max=30.0, step=0.1)
            self.angle_deg = gui.add_number("angle [deg]", 10.0, min=0.5, max=180.0, step=0.5)
            self.point = gui.add_dropdown("arrangement point", (NO_POINT, *point_names()), initial_value=NO_POINT)
            buttons: list[tuple[str, Callable[[], TryOnOp | None]]] = [
                ("Move out", lambda: self._panel_op("move", vector=self._outward())),
                ("Move up", lambda: self._panel_op("move", vector=[0.0, self._step(), 0.0])),
                ("Move down", lambda: self._panel_op("move", vector=[0.0, -self._step(), 0.0])),
                # in the panel's own plane: about its outward direction
                ("Rotate +", lambda: self._panel_op("rotate", angle=self._angle(), vector=self._outward())),
                ("Rotate -", lambda: self._panel_op("rotate", angle=-self._angle(), vector=self._outward())),
                ("Drag around +", lambda: self._panel_op("drag", angle=self._angle())),
                ("Drag around -", lambda: self._panel_op("drag", angle=-self._angle())),
                ("Drag up", lambda: self._panel_op("drag", vector=[0.0, self._step(), 0.0])),
                ("Drag down", lambda: self._panel_op("drag", vector=[0.0, -self._step(), 0.0])),
                ("Drag to picked point", self._to_target),
                ("Drag to arrangement point", self._to_point),
                ("Fix", lambda: self._panel_op("fix")),
                ("Unfix", lambda: self._panel_op("unfix")),
                ("Sew next seam", lambda: {"op": "sew", "seam": -1}),
                ("Unsew last seam", lambda: {"op": "unsew", "seam": -1}),
                ("Start sequential sewing", lambda: {"op": "start", "sewn": False}),
            ]
            self.buttons = {}
            for label, make in buttons:

                def click(_: viser.GuiEvent, make: Callable[[], TryOnOp | None] = make) -> None:
                    self.press(make)

                b = gui.add_button(label)
                b.on_click(click)
                self.buttons[label] = (b, make)

    # -- what the buttons send
    def _step(self) -> float:
        return float(self.step_cm.value) / 100.0

    def _angle(self) -> float:
        return math.radians(float(self.angle_deg.value))

    def _outward(self) -> list[float]:
        """step along the horizontal direction from the torso axis to the
        panel's centroid on screen (the front, +z, when nothing is shown)."""
        from couture.tryon import TORSO_AXIS_POINT, panel_vertices

        mesh, x = self.drape()
        d = np.array([0.0, 0.0, 1.0])
        if mesh is not None and x is not None and str(self.panel.value) in mesh.panel_names:
            c = np.asarray(x)[panel_vertices(mesh, str(self.panel.value))].mean(axis=0) - TORSO_AXIS_POINT
            c[1] = 0.0
            if np.linalg.norm(c) > 1e-6:
                d = c / np.linalg.norm(c)
        return (self._step() * d).tolist()

    def set_target(self, pick) -> None:
        """The point picked on the body (a BodyPick), or None to forget it."""
        self.target = pick
        if pick is not None:
            p = pick.point
            self.help.content = (
                f"picked the body ({pick.region}) at ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) m; "
                "**Drag to picked point** slides the panel there."
            )

    def set_refused(self, text: str) -> None:
        """A solver refused the last op sent (its reason); the drape stays."""
        self.help.content = f"**refused**: {text}"

    def _to_target(self) -> TryOnOp | None:
        """A drag of the panel about the torso axis and along it that takes
        its centroid (on screen) to the picked point's azimuth and height."""
        if self.target is None:
            self.help.content = "**drag to picked point**: click the body first."
            return None
        return self._drag_to(np.asarray(self.target.point), "drag to picked point")

    def _to_point(self) -> TryOnOp | None:
        """The drag to the chosen arrangement point (its place on the body shown)."""
        from couture.pattern.landmarks import arrangement_point

        name = str(self.point.value)
        if name == NO_POINT:
            self.help.content = "**drag to arrangement point**: choose an arrangement point first."
            return None
        return self._drag_to(arrangement_point(self.body(), name).position, "drag to arrangement point")

    def _drag_to(self, point: np.ndarray, what: str) -> TryOnOp | None:
        from couture.tryon import TORSO_AXIS_POINT, panel_vertices

        op = self._panel_op("drag")
        if op is None:
            return None
        mesh, x = self.drape()
        if mesh is None or x is None or op["panel"] not in mesh.panel_names:
            self.help.content = f"**{what}**: no drape of that panel on screen."
            return None
        c = np.asarray(x)[panel_vertices(mesh, op["panel"])].mean(axis=0) - TORSO_AXIS_POINT
        t = np.asarray(point) - TORSO_AXIS_POINT
        turn = math.atan2(t[0], t[2]) - math.atan2(c[0], c[2])  # about +y, counter-clockwise from above
        turn = (turn + math.pi) % (2.0 * math.pi) - math.pi
        return {**op, "angle": turn, "vector": [0.0, float(t[1] - c[1]), 0.0]}

    def _panel_op(self, op: str, **kw: Any) -> TryOnOp | None:
        panel = str(self.panel.value)
        if panel == NO_PANEL:
            self.help.content = f"**{op}**: pick a panel first."
            return None
        return {"op": op, "panel": panel, **kw}

    def press(self, make: Callable[[], TryOnOp | None]) -> TryOnOp | None:
        """Build one op and hand it to ``on_op`` (None: nothing sent, the help says why)."""
        op = make()
        if op is not None:
            self.help.content = f"sent **{op['op']}**" + (f" on {op['panel']}" if op.get("panel") else "")
            self.on_op(op)
        return op

    def click(self, label: str) -> TryOnOp | None:
        """What clicking the button ``label`` does (tests drive the panel with it)."""
        return self.press(self.buttons[label][1])

    def set_panels(self, names: list[str]) -> None:
        """The panels of the garment on screen."""
        opts = (NO_PANEL, *names)
        if tuple(self.panel.options) != opts:
            keep = self.panel.value if self.panel.value in opts else NO_PANEL
            self.panel.options = opts
            self.panel.value = keep  # type: ignore[misc]  # viser has the setter; mypy misses it
