"""The design controls on the 3D server's panel: sloper and its options,
the body, fabric, mesh resolution, the solver whose drapes are shown, the colour map
and its legend. Every change the designer makes becomes a new Design handed
to ``on_design``; :meth:`Controls.show_design` mirrors a design that came
from elsewhere without handing anything back."""

from __future__ import annotations

import functools
from typing import Any, Callable

import msgspec
import viser

from couture.pattern.limits import DIRECTIONAL_LIMITS
from couture.ui import colormaps
from couture.ui.state import FABRIC_PRESETS, LIBRARY_PRESETS, option_values, sloper_kinds, sloper_options
from couture.ui.widgets import nice_step, on_user_change
from schemas.design import Design, Fabric

DIRECTIONAL_FIELDS = tuple(DIRECTIONAL_LIMITS)
"""Fabric's optional directional fields, cleared by a custom (isotropic) entry"""


class Controls:
    """The "Garment", "Fabric" and "Simulation" folders."""

    def __init__(
        self,
        gui: viser.GuiApi,
        design: Callable[[], Design],
        *,
        on_design: Callable[[Design], None],
        on_solver: Callable[[str], None],
        on_field: Callable[[str], None],
    ):
        self.gui = gui
        self.design = design
        """the design the controls edit (the UI's current one)"""
        self.on_design, self.on_solver, self.on_field = on_design, on_solver, on_field
        d = design()
        with gui.add_folder("Garment"):
            self.sloper = gui.add_dropdown("sloper", self._sloper_choices(d), initial_value=d.sloper.kind)
            on_user_change(self.sloper, self.sloper_chosen)
            from couture import bodies

            names = bodies.names()
            self.body = gui.add_dropdown(
                "body", names, initial_value=d.body.name if d.body.name in names else "default"
            )
            on_user_change(self.body, self.body_chosen)
            self._option_folder = gui.add_folder("options")
            self.params: dict[str, Any] = {}
            """option name -> its slider"""
            self.tug_param = gui.add_dropdown("3D drag drives", ("(none)",), initial_value="(none)")
        with gui.add_folder("Fabric", expand_by_default=False):
            f = d.fabric
            names = (*FABRIC_PRESETS, "custom")
            self.preset = gui.add_dropdown("preset", names, initial_value=f.name if f.name in names else "custom")
            self.bend = gui.add_number("bending [N·m]", f.bend_stiffness, min=1e-9, max=1e-2, step=1e-9)
            self.stretch = gui.add_number("stretching [N/m]", f.stretch_stiffness, min=1.0, max=1e4, step=1.0)
            self.density = gui.add_number("density [kg/m²]", f.area_density, min=0.01, max=1.0, step=0.01)
            on_user_change(self.preset, self.preset_chosen)
            for h in (self.bend, self.stretch, self.density):
                on_user_change(h, self.fabric_changed)
        with gui.add_folder("Simulation", expand_by_default=False):
            self.solver = gui.add_dropdown("solver", ("any",), initial_value="any")
            on_user_change(self.solver, lambda: self.on_solver(str(self.solver.value)))
            r = d.resolution
            # small meshes (tests, slow machines) are legitimate: the range widens to the value
            self.coarse = gui.add_slider(
                "coarse vertices", min(100, r.coarse_vertices), 5000, 100, min(r.coarse_vertices, 5000)
            )
            self.fine = gui.add_slider(
                "fine vertices", min(300, r.fine_vertices), 40000, 100, min(r.fine_vertices, 40000)
            )
            for slider in (self.coarse, self.fine):
                on_user_change(slider, self.resolution_changed)
            self.field = gui.add_dropdown("colour map", colormaps.FIELDS, initial_value="none")
            on_user_change(self.field, self.field_chosen)
            self.legend = gui.add_html("")
        self._build_option_sliders(d)

    # -- design -> controls

    def show_design(self, d: Design) -> None:
        """Mirror a design (assignments run no user callbacks: see on_user_change)."""
        choices = self._sloper_choices(d)
        if tuple(self.sloper.options) != choices:
            self.sloper.options = choices
        if self.sloper.value != d.sloper.kind:
            self.sloper.value = d.sloper.kind  # type: ignore[misc]  # viser has the setter; mypy misses it
            self._build_option_sliders(d)
        elif self.params and not sloper_options(d.sloper.kind):
            self._build_option_sliders(d)  # free-form pieces only (an imported pattern): no sloper options
        values = option_values(d)  # a sloper drafted from the body follows the body
        for name, h in self.params.items():
            if name in values:
                h.value = float(values[name])
        if d.body.name in self.body.options:
            self.body.value = d.body.name  # type: ignore[misc]  # viser has the setter; mypy misses it
        f = d.fabric
        self.preset.value = f.name if f.name in FABRIC_PRESETS else "custom"  # type: ignore[misc]  # viser has the setter; mypy misses it
        self.bend.value, self.stretch.value, self.density.value = f.bend_stiffness, f.stretch_stiffness, f.area_density  # type: ignore[misc]  # viser has the setter; mypy misses it
        for slider, v in ((self.coarse, d.resolution.coarse_vertices), (self.fine, d.resolution.fine_vertices)):
            slider.value = int(min(max(v, slider.min), slider.max))  # type: ignore[misc]  # viser has the setter; mypy misses it

    def show_solvers(self, live: list[str], selected: str) -> None:
        """The solver choices: 'any' and the live solvers; a chosen solver
        that died stays chosen (its last drape stays on screen)."""
        opts = ("any", *live)
        if selected not in opts:
            opts = (*opts, selected)
        if tuple(self.solver.options) != opts:
            self.solver.options = opts
            self.solver.value = selected  # type: ignore[misc]  # viser has the setter; mypy misses it

    def show_legend(self, scale: colormaps.ColorScale | None) -> None:
        self.legend.content = scale.legend_html() if scale is not None else ""

    @property
    def tug_option(self) -> str:
        """The sloper option a 3D drag drives ('' for none)."""
        v = str(self.tug_param.value)
        return "" if v == "(none)" else v

    def _build_option_sliders(self, d: Design) -> None:
        for h in self.params.values():
            h.remove()
        self.params = {}
        opts = sloper_options(d.sloper.kind)
        values = option_values(d)
        with self._option_folder:
            for o in opts:
                val = float(values.get(o.name, o.default))
                step = 1.0 if o.integer else nice_step(o.max - o.min)
                label = f"{o.name} [{o.unit}]" if o.unit else o.name
                h = self.gui.add_slider(label, o.min, o.max, step, min(max(val, o.min), o.max))
                on_user_change(h, functools.partial(self.param_changed, o.name))
                self.params[o.name] = h
        names = tuple(o.name for o in opts) or ("(none)",)
        self.tug_param.options = names
        # a style option by default (the body measurements come first in the tables)
        self.tug_param.value = "length" if "length" in names else names[0]  # type: ignore[misc]  # viser has the setter; mypy misses it

    # -- what the designer did -> a new design

    @staticmethod
    def _sloper_choices(d: Design) -> tuple[str, ...]:
        """The sloper dropdown's entries: the slopers, and first the design's own
        kind when it is none of them ('none': an imported design of pieces)."""
        kinds = tuple(sloper_kinds())
        return kinds if d.sloper.kind in kinds else (d.sloper.kind, *kinds)

    def sloper_chosen(self) -> None:
        d = self.design()
        if str(self.sloper.value) == d.sloper.kind:
            return
        new = msgspec.structs.replace(
            d, sloper=msgspec.structs.replace(d.sloper, kind=str(self.sloper.value), params={})
        )
        self._build_option_sliders(new)
        self.on_design(new)

    def param_changed(self, name: str) -> None:
        d = self.design()
        params = {**d.sloper.params, name: float(self.params[name].value)}
        self.on_design(msgspec.structs.replace(d, sloper=msgspec.structs.replace(d.sloper, params=params)))

    def preset_chosen(self) -> None:
        p = FABRIC_PRESETS.get(str(self.preset.value))
        if p is None:
            return
        self.bend.value, self.stretch.value, self.density.value = p.bend_stiffness, p.stretch_stiffness, p.area_density  # type: ignore[misc]  # viser has the setter; mypy misses it
        if p.name in LIBRARY_PRESETS:
            # a library fabric whole: its directional values, density and skin friction
            self._set_fabric(msgspec.structs.replace(p))
            return
        self._set_fabric(
            msgspec.structs.replace(
                self.design().fabric,
                name=p.name,
                bend_stiffness=p.bend_stiffness,
                stretch_stiffness=p.stretch_stiffness,
                area_density=p.area_density,
            )
        )

    def fabric_changed(self) -> None:
        self.preset.value = "custom"  # type: ignore[misc]  # viser has the setter; mypy misses it
        self._set_fabric(
            msgspec.structs.replace(
                self.design().fabric,
                name="custom",
                bend_stiffness=float(self.bend.value),
                stretch_stiffness=float(self.stretch.value),
                area_density=float(self.density.value),
                # a custom entry is isotropic: the three numbers shown are all it has
                **dict.fromkeys(DIRECTIONAL_FIELDS),
            )
        )

    def body_chosen(self) -> None:
        """Another body: the same garment, re-draped from its current drape."""
        d = self.design()
        self.on_design(msgspec.structs.replace(d, body=msgspec.structs.replace(d.body, name=str(self.body.value))))

    def _set_fabric(self, fabric: Fabric) -> None:
        self.on_design(msgspec.structs.replace(self.design(), fabric=fabric))

    def resolution_changed(self) -> None:
        d = self.design()
        res = msgspec.structs.replace(
            d.resolution, coarse_vertices=int(self.coarse.value), fine_vertices=int(self.fine.value)
        )
        self.on_design(msgspec.structs.replace(d, resolution=res))

    def field_chosen(self) -> None:
        self.on_field(str(self.field.value))


def _given_values(d: Design) -> dict[str, Any]:
    """The option values the design gives: its params, over its body's
    measurements for a body-fitted sloper (``couture.pattern.draft.option_values``);
    its params alone where that fails (an unknown sloper or body)."""
    from couture.pattern.draft import option_values
    from couture.pattern.errors import PatternError

    try:
        return option_values(d)
    except PatternError:
        return dict(d.sloper.params)
