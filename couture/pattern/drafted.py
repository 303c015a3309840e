"""The drafted pattern: what the pattern model hands to the remesher.

This is the contract between ``couture.pattern`` (slopers, strokes, validation,
I/O, placement) and ``couture.remesh`` (triangle meshes, seams, Ψ). The pattern
side drafts a design into flat panels whose outlines are dense polylines in
metres; the remesher meshes them without moving those polyline vertices, so a
pattern edit's Jacobian on the polyline vertices is all the remesher needs to
build Ψ (SC §6): linear along the boundary, positive mean value coordinates
inside.

Invariant the remesher relies on: for one design, the number of polyline
vertices of every outline and hole does not change when sloper parameters or
stroke values change (only their positions do), so finite differences and
Jacobians over parameters are well defined.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Segment:
    """A named boundary piece of a panel (seam segment / interface).

    Covers outline vertices ``start, start+1, ..., stop`` (indices wrap modulo
    the outline length; ``stop`` may be smaller than ``start``).
    """

    name: str
    start: int
    stop: int
    hole: int = -1
    """-1: the segment lies on the outline; h >= 0: on ``holes[h]`` (interior
    dart sides), indices then refer to that hole polyline"""


@dataclass
class Placement:
    """Initial 3D placement of a panel around the body (Meng 2010 / Volino 2005).

    kind 'wrap' (what the slopers use): rows at material heights ``rows_y``;
    on row i, material x lies at arc length ``x - rows_x0[i]`` (from theta =
    0, toward theta = pi/2) along the closed polar curve ``rows_radius[i]``
    (radii at theta_k = 2 pi k / K) about the axis, at ``rows_axial[i]`` along
    it from ``origin``; rows are interpolated linearly (exact mapping:
    ``couture.pattern.placement.place``).
    kind 'cylinder': material x wraps around the vertical axis through
    ``origin`` at ``radius`` starting at angle ``angle0`` [rad] (angle grows
    with x / radius), material y maps to world y (up) shifted by origin[1].
    theta = 0 is world +z (the front), theta = pi/2 world +x. Optional
    ``axis``/``ref``/``taper`` tilt the axis and make it a cone; the exact
    mapping is ``couture.pattern.placement.place``.
    kind 'plane': world = origin + X[:, 0] * u + X[:, 1] * v.
    kind 'grid': world positions ``grid_pos`` at the material grid
    ``grid_x`` x ``grid_y``, bilinear between (a collar laid on the neckline
    it is sewn to: ``couture.pattern.pieces.collar_placements``).
    """

    kind: str
    origin: np.ndarray
    """[m], shape (3,)"""
    radius: float = 0.0
    """[m], cylinder only"""
    angle0: float = 0.0
    """[rad], cylinder only"""
    u: np.ndarray | None = None
    """unit 3-vector for material x, plane only"""
    v: np.ndarray | None = None
    """unit 3-vector for material y, plane only"""
    flip: bool = False
    """mirror material x (a back panel seen from behind), cylinder only"""
    axis: np.ndarray | None = None
    """unit 3-vector of the cylinder axis (material +y); None: world up. Tilted
    for sleeves and trouser legs"""
    ref: np.ndarray | None = None
    """3-vector of the theta = 0 direction (projected normal to the axis);
    None: world +z (the front). theta grows toward axis x ref"""
    taper: float = 0.0
    """radius growth per metre of material -y (a cone: flared skirts); the
    radius at material y is ``radius - taper * y``"""
    rows_y: np.ndarray | None = None
    """[m] material y of each row, increasing, shape (m,), wrap only"""
    rows_axial: np.ndarray | None = None
    """[m] position of each row along the axis from ``origin``, shape (m,), wrap only"""
    rows_x0: np.ndarray | None = None
    """[m] material x at arc length 0 (theta = 0) of each row, shape (m,), wrap only"""
    rows_radius: np.ndarray | None = None
    """[m] polar radius of each row's cross-section curve, shape (m, K), wrap only"""
    grid_x: np.ndarray | None = None
    """[m] material x of the grid's columns, increasing, shape (nx,), grid only"""
    grid_y: np.ndarray | None = None
    """[m] material y of the grid's rows, increasing, shape (ny,), grid only"""
    grid_pos: np.ndarray | None = None
    """[m] world position of each grid point, shape (ny, nx, 3), grid only"""


@dataclass
class Panel:
    """A closed edge loop with holes: one piece of fabric, flat, in metres."""

    name: str
    outline: np.ndarray
    """boundary polyline [m], shape (k, 2), counter-clockwise, not closed (last != first)"""
    holes: list[np.ndarray] = field(default_factory=list)
    """hole polylines [m], each shape (h, 2), clockwise"""
    segments: list[Segment] = field(default_factory=list)
    """named boundary pieces, used by seams"""
    placement: Placement | None = None
    """initial 3D placement; None: flat at z = 0"""
    grain: float = 0.0
    """[rad] grain direction from material +y, counter-clockwise: 0 is straight
    grain along the panel's vertical (every sloper's material y), pi/4 bias"""


@dataclass
class SeamSpec:
    """A stitch: two segments to sew. Lengths may differ (gathers, pleats)."""

    a_panel: str
    a_segment: str
    b_panel: str
    b_segment: str
    reverse: bool = True
    """traverse b backwards while a goes forwards (the usual case for two
    counter-clockwise panels sewn edge to edge)"""


@dataclass
class DraftedPattern:
    """A whole garment, drafted: panels and seams."""

    panels: list[Panel]
    seams: list[SeamSpec] = field(default_factory=list)

    def panel(self, name: str) -> Panel:
        for p in self.panels:
            if p.name == name:
                return p
        raise KeyError(f"no panel named {name!r}; panels are {[p.name for p in self.panels]}")


@dataclass
class PanelJacobian:
    """How a panel's polylines move per unit pointer motion for one edit.

    ``outline[i] @ dd`` is the motion [m] of outline vertex i for a pointer
    motion dd [m] (2,), i.e. SC's 2x2 tensor Ψ_i on the boundary.
    """

    outline: np.ndarray
    """shape (k, 2, 2)"""
    holes: list[np.ndarray] = field(default_factory=list)
    """each shape (h, 2, 2)"""


def segment_points(panel: Panel, seg: Segment) -> np.ndarray:
    """Polyline vertices of a segment, start to stop inclusive (wrapping)."""
    P = panel.outline if seg.hole < 0 else panel.holes[seg.hole]
    k = len(P)
    n = (seg.stop - seg.start) % k
    if n == 0:
        n = k if seg.hole >= 0 and seg.start == seg.stop else 0
    return P[(seg.start + np.arange(n + 1)) % k]
