"""The design: what a designer edits, carried by the ``pattern`` message and
stored as our JSON pattern file (``couture/design/v1``).

Shared by ``schemas.messages`` (the bus) and ``couture.pattern`` (drafting,
validation, file I/O). Strokes ride the sloper: their parameters are relative
to the drafted sloper (segment names and curve parameters, not absolute
coordinates), so they survive sloper parameter changes.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

import msgspec

DESIGN_SCHEMA = "couture/design/v1"

StiffnessScale = Annotated[float, msgspec.Meta(gt=0.0, le=1e6)]
"""a dimensionless factor on a default stiffness: positive and finite (a
decoded message or file outside (0, 1e6] is rejected naming the field)"""


Clearance = Annotated[float, msgspec.Meta(ge=0.002, le=0.1)]
"""[m] a placed piece's gap from the body's section: 2 mm .. 10 cm"""


class Fabric(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """Material of every panel (SC Table 1 ranges in the comments; the
    allowed ranges, checked by the remesher and the solvers, are
    ``couture.pattern.limits.FABRIC_LIMITS``)."""

    name: str = "cotton"
    stretch_stiffness: float = 20.0
    """in-plane stiffness [N/m] (Young's modulus x thickness), 10..2000"""
    poisson_ratio: float = 0.3
    """dimensionless, 0 <= nu < 0.5"""
    bend_stiffness: float = 1e-6
    """[N m], 1e-8..3e-4"""
    area_density: float = 0.15
    """[kg/m^2], 0.08..0.2"""
    friction_static: float = 0.5
    """Coulomb static coefficient against the body"""
    friction_kinetic: float = 0.3
    """Coulomb kinetic coefficient against the body"""
    # A woven or knitted fabric's directions (all optional: a fabric that gives
    # none of them is isotropic, as above). Warp is the grain line
    # (Panel.grain), weft across it in the fabric's plane.
    warp_stiffness: float | None = None
    """[N/m] tensile stiffness along the warp (E1 x thickness); None: stretch_stiffness"""
    weft_stiffness: float | None = None
    """[N/m] tensile stiffness along the weft (E2 x thickness); None: stretch_stiffness"""
    shear_stiffness: float | None = None
    """[N/m] in-plane shear stiffness (G12 x thickness), what a bias pull meets;
    None: the isotropic value stretch_stiffness / (2 (1 + poisson_ratio))"""
    bend_warp: float | None = None
    """[N m] bending rigidity of a strip cut along the warp (its long axis the
    warp, as ASTM D1388 cuts it); None: bend_stiffness"""
    bend_weft: float | None = None
    """[N m] bending rigidity of a strip cut along the weft; None: bend_stiffness"""
    bend_bias: float | None = None
    """[N m] bending rigidity of a strip cut on the bias (45 degrees); None:
    the mean of bend_warp and bend_weft"""
    thickness: float | None = None
    """[m] the fabric's thickness (information; the model is a surface)"""


class Sloper(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """A drafted base pattern: its kind and its options (each option's
    default/min/max/unit is data in couture.pattern)."""

    kind: str = "skirt"
    """'skirt', 'dress', 'shirt', 'trousers', ... (``couture.pattern.SLOPERS``), or
    'none': no sloper (a design of free-form ``pieces`` only)"""
    params: dict[str, float] = {}
    """option name -> value in the option's unit (SI: metres, radians, counts)"""


class Stroke(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """An edit that rides the sloper: 'curve', 'dart', 'seam', 'symmetry', 'hole'."""

    id: str
    """stable identifier, used by edit messages to name the element"""
    kind: str
    panel: str = ""
    """panel the stroke belongs to ('' for strokes between panels, e.g. seams)"""
    params: dict[str, Any] = {}
    """kind-specific values, validated by couture.pattern (names the element on error)"""


class Body(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """The mannequin."""

    name: str = "default"
    """'default' is the embedded A-pose mannequin; 'XS', 'S', 'M', 'L', 'XL' the
    graded bodies shipped with couture (``couture bodies list``); with
    ``measurements``, a name of its own (e.g. a measurement set's)"""
    measurements: dict[str, float] | None = None
    """the body's own ISO 8559-1 measurements [m] ('height', 'bust_girth',
    'waist_girth', 'hip_girth', 'inseam', 'waist_height'; any subset with a girth): every
    process builds the same body from them (``couture.bodies.warp``, cached);
    None: ``name`` is a shipped body"""


class SceneFlags(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """Which terms the scene needs (absent terms are never built), and the
    factors on the default seam and contact stiffnesses."""

    body: bool = True
    gravity: bool = True
    seams: bool = True
    friction: bool = True
    seam_stiffness_scale: StiffnessScale = 1.0
    """dimensionless factor on the default seam spring stiffness
    (``couture.cloth.model.SEAM_STIFFNESS_PER_MU`` x the fabric's shear modulus mu)"""
    contact_stiffness_scale: StiffnessScale = 1.0
    """dimensionless factor on the default body contact stiffness
    (``couture.cloth.model.CONTACT_STIFFNESS_PER_MU`` x mu)"""
    friction_model: Literal["anchors", "huber"] = "anchors"
    """how friction enters the equilibrium (``couture.cloth.model.Scene.friction_model``):
    'anchors', springs that slip in events; 'huber', one smooth elasto-plastic
    potential with lagged Coulomb limits, carried from the coarse level to the fine one"""


class Resolution(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """Target mesh sizes for cascadic refinement (each 50..250000,
    ``couture.pattern.limits.RESOLUTION_LIMITS``)."""

    coarse_vertices: int = 1600
    fine_vertices: int = 10000


class PiecePlacement(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """Where a free-form piece starts around the body (the solver sews it from
    there): pieces of one ring are wrapped round one axis in ``position``
    order, tiling the body's section there (``couture.pattern.placement.fit_ring``)."""

    ring: Literal[
        "torso", "band", "neck", "left_leg", "right_leg", "left_arm", "right_arm", "point", "inside", "flat"
    ] = "torso"
    """'torso': round the torso, theta = 0 at the front; 'left_leg' /
    'right_leg': round that leg (a trouser leg's front and back, open at the
    inner side above the crotch, where the other leg's panels join); 'left_arm'
    / 'right_arm': a sleeve round that arm, its top centre on top of the arm;
    'band': a waistband round the torso, a ring of its own above the torso
    ring's top; 'neck': a collar (or a neck band): laid on the neckline
    it is sewn to as the other pieces are placed, or, sewn to nothing, round
    the neck, its neck edge (its bottom) at the body's neck base
    (``couture.pattern.landmarks``);
    'inside': a facing laid just inside the piece it is sewn to (its seams
    say which; ``clearance`` nearer the body than that piece, default 3 mm);
    'point': one piece laid with its centre at the arrangement point
    ``point`` and wrapped round the body's local axis there (CLO's
    arrangement points);
    'flat': laid flat in front of the body (not wrapped: a piece the importer
    could not place)"""
    position: int = 0
    """order round the ring, by increasing theta (front, the body's left side,
    back, its right side)"""
    angle: float = 0.0
    """[rad] centre angle of the ring's first piece (theta = 0 is the front,
    pi/2 the body's left); read from the ring's first piece only"""
    height: float = 0.27
    """[m] world height (y) of material y = 0 (each piece's top); read from
    the ring's first piece only (a leg: where its axis crosses that height; an
    arm: ignored, the sleeve's top hangs from the shoulder; 'neck': the top
    on the default body, moved with the body's neck base on another; 'point':
    ignored, the point gives the height)"""
    landmark: Literal["waist", "neck"] = "waist"
    """ring 'torso' (read from the ring's first piece): the body landmark its
    ``height`` moves with on another body than the default: 'waist' (a skirt,
    trousers: the height is the default body's waist region) or 'neck' (a
    top: the height is the default body's neck base, where the shoulders'
    neck ends lie; on another body the ring moves with its neck base, and
    down where the armholes' bottoms would otherwise not clear its
    armpits, ``couture.pattern.placement.ARMPIT_CLEAR``)"""
    point: str = ""
    """ring 'point': the arrangement point's name ('front_waist', 'back_neck',
    'left_upper_arm', ...: ``couture.pattern.landmarks.point_names``)"""
    clearance: Clearance | None = None
    """[m] ring 'point' (and 'neck'): the gap between the body's section and the
    piece, 0.002..0.1; None: the ring's default (0.015)"""


class Piece(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """A free-form panel: a pattern piece given by its sew line (an imported
    piece, ``couture import``), not drafted from a sloper. Its boundary
    segments are the runs between consecutive ``corners``, named ``e0``,
    ``e1``, ...; seams between them are ``seam`` strokes."""

    name: str
    """panel name, unique in the design"""
    outline: list[tuple[float, float]]
    """[m] sew line, counter-clockwise, not closed, shape (k, 2); material y up"""
    holes: list[list[tuple[float, float]]] = []
    """[m] sew lines of holes, each clockwise, shape (h, 2)"""
    corners: list[int] = []
    """outline indices where segments start, increasing; segment ``e<i>`` runs
    from ``corners[i]`` to ``corners[i + 1]`` (the last wraps to ``corners[0]``);
    empty: one segment ``e0`` round the whole outline"""
    notches: list[tuple[float, float]] = []
    """[m] notch positions on the sew line, shape (n, 2)"""
    grain: float = 0.0
    """[rad] grain direction from material +y, counter-clockwise"""
    role: str = ""
    """'front', 'back', 'side', 'sleeve', 'waistband', 'collar', 'cuff', ... ('' unknown)"""
    source: str = ""
    """where it came from: the file and the piece's name there (and 'mirrored')"""
    placement: PiecePlacement = msgspec.field(default_factory=PiecePlacement)
    mirror_of: str = ""
    """the other piece of a 'Cut 2' pair (one piece cut twice, once face down),
    '' for none; both pieces name each other. This piece is then the mirror
    image of that one: the same number k of outline points, point ``j`` here
    at (c - x, y) of its point ``(mirror_index - j) mod k`` (c fixed), corners
    likewise; an edit of a point or curve of either applies mirrored to both
    (``couture.pattern.pieces``). An optional field added within
    ``couture/design/v1``: older designs have none (each piece edits alone)"""
    mirror_index: int = 0
    """which point of ``mirror_of`` point 0 of this piece mirrors (the same number on both pieces)"""


class Design(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """A whole garment design: a sloper (``kind`` 'none' for none) with its
    strokes, and free-form pieces (imported patterns), sewn by seam strokes."""

    sloper: Sloper = msgspec.field(default_factory=Sloper)
    strokes: list[Stroke] = []
    fabric: Fabric = msgspec.field(default_factory=Fabric)
    body: Body = msgspec.field(default_factory=Body)
    scene: SceneFlags = msgspec.field(default_factory=SceneFlags)
    resolution: Resolution = msgspec.field(default_factory=Resolution)
    panel_fabrics: dict[str, Fabric] = {}
    """panel name -> that panel's own fabric (a waistband, a collar, a lining);
    a panel not named here is cut from ``fabric``"""
    pieces: list[Piece] = []
    """free-form panels besides the sloper's (an old file without the field
    has none: ``couture/design/v1`` gained it as an optional field)"""
