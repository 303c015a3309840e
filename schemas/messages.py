"""Every message that crosses the bus (DESIGN.md §2), one msgspec Struct each.

Each type has a versioned name ``couture/<name>/v<k>`` (``TYPE``) used in the
payload (the ``schema`` field), as the MCAP schema name, and in errors. The
wire format is msgpack; arrays are :class:`schemas.arrays.Array` (dtype +
shape + raw little-endian bytes). Construct messages with numpy arrays or
Arrays alike (``DrapeMsg(x=x, level="fine", ...)``); read arrays back with
``msg.x.numpy()``.

``encode(msg)`` validates and serializes; ``decode(data, expected_type)``
parses and validates, raising only :class:`SchemaError`, whose message names
the schema and the field path. Header fields (``seq``, ``stamp_ns``) are
filled by the bus publisher when left at 0.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, ClassVar, Literal, TypeVar, overload

import msgspec
import numpy as np

from schemas.arrays import DTYPES, FLOAT_DTYPES, Array
from schemas.design import Design


class SchemaError(ValueError):
    """A message that is not a valid couture message; the text names the
    schema (or 'unknown schema') and the field path."""


@dataclass(frozen=True)
class ArraySpec:
    """What an array field must look like: allowed wire dtypes, a shape whose
    entries are ints (fixed) or names (equal across fields of one message),
    and whether every element must be finite."""

    dtypes: tuple[str, ...]
    shape: tuple[int | str, ...]
    finite: bool = False
    optional: bool = False


F64 = ("float64",)
I32 = ("int32",)


class Message(msgspec.Struct, kw_only=True):
    """Header carried by every message."""

    schema: str = ""
    """versioned type name, e.g. 'couture/drape/v1' (set automatically)"""
    version: int = 1
    """schema version, the k of '/v<k>' (set automatically)"""
    seq: int = 0
    """per-publisher sequence number, from 1 (filled by the publisher)"""
    stamp_ns: int = 0
    """send time, Unix epoch [ns] (filled by the publisher)"""
    generation: int = 0
    """pattern generation this message belongs to (stale work is dropped)"""

    TYPE: ClassVar[str] = ""
    ARRAYS: ClassVar[dict[str, ArraySpec]] = {}

    def __post_init__(self) -> None:
        if not self.schema:
            self.schema = self.TYPE
            self.version = _version_of(self.TYPE)
        for name, spec in self.ARRAYS.items():
            v = getattr(self, name)
            if v is not None and not isinstance(v, Array):
                a = np.asarray(v)
                wire = _wire_name_or_none(a.dtype)
                setattr(self, name, Array.from_numpy(a, wire if wire in spec.dtypes else spec.dtypes[0]))

    def check(self) -> None:
        """Type-specific checks beyond shapes (raise SchemaError with the field)."""


def _version_of(type_name: str) -> int:
    return int(type_name.rsplit("/v", 1)[1])


def _wire_name_or_none(dt: np.dtype) -> str | None:
    for name, d in DTYPES.items():
        if d == dt:
            return name
    return None


# ---------------------------------------------------------------------------
# messages


class PatternMsg(Message, kw_only=True):
    """The full design. ui, scripts -> remesher (and every node that wants the
    current design). Key ``pattern``."""

    TYPE: ClassVar[str] = "couture/pattern/v1"
    schema: str = "couture/pattern/v1"
    design: Design = msgspec.field(default_factory=Design)
    """sloper, strokes, fabric, body, scene flags, resolution"""
    source: str = ""
    """who published it: 'ui', 'client', 'replay', ..."""
    name: str = ""
    """human-readable design name (file stem)"""
    design_id: str = ""
    """identity of this design, chosen by its publisher unique for good (a
    uuid); the remesher's meshes name it. The header's ``generation`` is only
    the number the publisher asks for: the remesher numbers designs, and the
    meshes (hence the drapes) carry the number it gave"""

    def identity(self) -> str:
        """The design's identity: ``design_id``, or for a pattern published
        without one, a name every receiver derives alike from its header
        (publisher, sequence number, send time)."""
        return self.design_id or f"unnamed:{self.source}:{self.seq}:{self.stamp_ns}"


class EditMsg(Message, kw_only=True):
    """A drag of a pattern element. ui -> remesher (Ψ on press), sensitivity
    (predictions while dragging), solver (refine on release). Key ``edit``.

    For a 2D drag, ``d`` is the pointer displacement in the pattern plane since
    press. For a 3D drag on the drape, ``picked_*``, ``view_proj`` and
    ``viewport_px`` say where the cloth was grabbed and how to project its
    sensitivity to the screen (SC §5: Δg = ŝ·Δd / |ŝ|²); ``d`` is then the
    screen displacement in pixels.
    """

    TYPE: ClassVar[str] = "couture/edit/v1"
    ARRAYS: ClassVar[dict[str, ArraySpec]] = {
        "d": ArraySpec(F64, (2,), finite=True),
        "picked_bary": ArraySpec(F64, (3,), finite=True, optional=True),
        "view_proj": ArraySpec(F64, (4, 4), finite=True, optional=True),
    }
    schema: str = "couture/edit/v1"
    edit_id: str = ""
    """identifier shared by the press, drags and release of one gesture"""
    phase: Literal["press", "drag", "release"] = "drag"
    element: str = ""
    """id of the pattern element dragged (stroke id, 'panel:seg', sloper option name)"""
    dofs: list[str] = []
    """degrees of freedom of the element that the drag moves, e.g. ['x', 'y']"""
    d: Array = msgspec.field(default_factory=lambda: Array.from_numpy(np.zeros(2)))
    """pointer displacement since press: [m] in the pattern plane (2D drag), [px] on screen (3D drag), shape (2,), float64"""
    param: str = ""
    """sloper parameter driven by a 3D drag or a slider ('' for a 2D element drag)"""
    picked_vertex: int = -1
    """3D drag: fine-mesh vertex nearest the pick, -1 for a 2D drag"""
    picked_tri: int = -1
    """3D drag: triangle under the pointer, -1 for a 2D drag"""
    picked_bary: Array | None = None
    """3D drag: barycentric coordinates of the pick in picked_tri, shape (3,), float64"""
    view_proj: Array | None = None
    """3D drag: camera view-projection matrix (world [m] -> clip), shape (4, 4), float64, row-major"""
    viewport_px: list[int] = []
    """3D drag: viewport [width, height] in pixels"""


class MeshMsg(Message, kw_only=True):
    """A simulation mesh. remesher -> solver, sensitivity, ui. Keys
    ``mesh/coarse``, ``mesh/fine``; published once per mesh (Ψ of a press
    travels apart, :class:`PsiMsg`).

    Converts to/from :class:`couture.mesh.GarmentMesh` with
    :func:`schemas.convert.mesh_to_msg` / :func:`schemas.convert.msg_to_mesh`.
    """

    TYPE: ClassVar[str] = "couture/mesh/v1"
    ARRAYS: ClassVar[dict[str, ArraySpec]] = {
        "X": ArraySpec(F64, ("n", 2), finite=True),
        "x0": ArraySpec(F64, ("n", 3), finite=True),
        "tris": ArraySpec(I32, ("m", 3)),
        "tri_panel": ArraySpec(I32, ("m",)),
        "seam_emitters": ArraySpec(I32, ("k",)),
        "seam_edges": ArraySpec(I32, ("k", 2)),
        "seam_weights": ArraySpec(F64, ("k",), finite=True),
        "pinned": ArraySpec(I32, ("p",)),
        "fine_parent_tri": ArraySpec(I32, ("n",), optional=True),
        "fine_bary": ArraySpec(F64, ("n", 3), finite=True, optional=True),
    }
    schema: str = "couture/mesh/v1"
    level: Literal["coarse", "fine"] = "fine"
    """cascadic refinement level"""
    mesh_generation: int = 0
    """bumps whenever the remesher changes this level's topology or rest shape (flips, remesh)"""
    X: Array
    """rest (pattern) positions [m], shape (n, 2), float64"""
    x0: Array
    """initial 3D placement [m], shape (n, 3), float64"""
    tris: Array
    """triangles, counter-clockwise in X, shape (m, 3), int32"""
    tri_panel: Array
    """panel index of each triangle, shape (m,), int32"""
    panel_names: list[str] = []
    """panel names indexed by tri_panel"""
    panel_grain: list[float] = []
    """[rad] each panel's grain (warp from material +y, counter-clockwise),
    indexed by tri_panel; [] (an older message): every panel 0, straight grain"""
    seam_emitters: Array
    """emitting vertex of each seam spring, shape (k,), int32"""
    seam_edges: Array
    """receiving edge (a, b) of each seam spring, shape (k, 2), int32"""
    seam_weights: Array
    """receiving point (1-w) x_a + w x_b, shape (k,), float64"""
    pinned: Array
    """vertices held at x0, shape (p,), int32"""
    design_id: str = ""
    """design_id of the pattern this mesh was drafted from ('' when it had none)"""
    fine_parent_tri: Array | None = None
    """fine level only: coarse triangle containing each fine vertex (in X), shape (n,), int32"""
    fine_bary: Array | None = None
    """fine level only: barycentric coordinates in fine_parent_tri, shape (n, 3), float64"""

    def check(self) -> None:
        n = self.X.shape[0]
        for name in ("tris", "seam_emitters", "seam_edges", "pinned"):
            a = getattr(self, name).numpy()
            if a.size and (a.min() < 0 or a.max() >= n):
                raise SchemaError(f"{self.TYPE}: field `$.{name}`: vertex index outside [0, {n})")
        tp = self.tri_panel.numpy()
        if self.panel_names and tp.size and (tp.min() < 0 or tp.max() >= len(self.panel_names)):
            raise SchemaError(f"{self.TYPE}: field `$.tri_panel`: panel index outside [0, {len(self.panel_names)})")
        if self.panel_grain:
            n_panels = max(len(self.panel_names), int(tp.max()) + 1 if tp.size else 0)
            if len(self.panel_grain) != n_panels:
                raise SchemaError(
                    f"{self.TYPE}: field `$.panel_grain`: {len(self.panel_grain)} angles for {n_panels} panels"
                )
            if not all(math.isfinite(g) for g in self.panel_grain):
                raise SchemaError(f"{self.TYPE}: field `$.panel_grain`: angles must be finite [rad]")


class PsiMsg(Message, kw_only=True):
    """Ψ of a press: how the rest shape of one mesh level moves with the
    gesture's design point (SC §4). remesher -> sensitivity (and any node
    that wants it). Keys ``psi/coarse``, ``psi/fine``, one message per press
    and level; the mesh it belongs to was published before on
    ``mesh/<level>`` and is named by ``generation`` (the header) and
    ``mesh_generation``. Kept as the topic's history, so a node restarted
    mid-drag gets the gesture's Ψ with the mesh."""

    TYPE: ClassVar[str] = "couture/psi/v1"
    ARRAYS: ClassVar[dict[str, ArraySpec]] = {
        "psi": ArraySpec(F64, ("n", 2, 2), finite=True),
    }
    schema: str = "couture/psi/v1"
    level: Literal["coarse", "fine"] = "fine"
    """mesh level Ψ lives on"""
    mesh_generation: int = 0
    """mesh_generation of the mesh Ψ lives on"""
    design_id: str = ""
    """design_id of that mesh's pattern ('' when it had none)"""
    edit_id: str
    """the gesture (its press) Ψ belongs to"""
    psi: Array
    """dX_i = psi[i] @ dd for vertex i: rest-position change [m] per unit of
    the edit's design point d, shape (n, 2, 2), float64 (n: the mesh's vertices)"""

    def check(self) -> None:
        if not self.edit_id:
            raise SchemaError(f"{self.TYPE}: field `$.edit_id`: Ψ must name the gesture it belongs to")


class DrapeMsg(Message, kw_only=True):
    """3D positions of a mesh. solver -> ui, sensitivity (keys ``drape/coarse``,
    ``drape/fine``); sensitivity -> ui (key ``drape/predicted``)."""

    TYPE: ClassVar[str] = "couture/drape/v1"
    ARRAYS: ClassVar[dict[str, ArraySpec]] = {
        "x": ArraySpec(FLOAT_DTYPES, ("n", 3), finite=True),
        "d": ArraySpec(F64, (2,), finite=True, optional=True),
    }
    schema: str = "couture/drape/v1"
    level: Literal["coarse", "fine", "predicted"] = "fine"
    """mesh level, or 'predicted' for sensitivity previews (on the coarse mesh unless stated)"""
    mesh_level: Literal["coarse", "fine"] = "coarse"
    """for 'predicted': which mesh x lives on (ignored otherwise)"""
    mesh_generation: int = 0
    """mesh_generation of the mesh x belongs to"""
    x: Array
    """draped positions [m], shape (n, 3), float32 or float64"""
    residual: float = float("nan")
    """relative force residual ||R_free|| / ||F_gravity|| (couture.solvers.base); NaN if unknown"""
    iterations: int = 0
    """solver iterations so far (0 for predictions)"""
    solver: str = ""
    """name of the publishing solver node, '' for predictions"""
    method: str = ""
    """'kinetic', 'newton', 'verlet', 'linear', 'gmls', ..."""
    wall_time_s: float = 0.0
    """compute time spent on this result [s]"""
    converged: bool = False
    """residual below the requested tolerance"""
    diagnosis: str = ""
    """why the solver stopped if not converged ('' otherwise)"""
    d: Array | None = None
    """design point of a prediction (edit displacement), shape (2,), float64"""
    edit_id: str = ""
    """gesture a prediction belongs to"""
    error_estimate: float | None = None
    """cheap error estimate of a prediction (its relative force residual)"""
    error_estimate_m: float | None = None
    """estimated distance of a prediction from the true equilibrium [m] (the
    largest vertex motion of one Newton correction); None when not computed.
    An optional field added within v1: older readers ignore it"""
    terms: list[str] = []
    """the energy terms the solver built for this drape's model (of membrane,
    bending, gravity, seams, contact, friction: only what the design's scene
    needs; [] for predictions and peers that do not say). An optional field
    added within v1: older readers ignore it"""
    request_id: str = ""
    """solve request this drape answers, '' for bus-driven solves"""
    final: bool = True
    """False for progress snapshots published while a solve runs; True for a
    level's result (converged or stopped with a diagnosis) and for predictions"""


TRYON_OPS = ("start", "move", "rotate", "drag", "fix", "unfix", "sew", "unsew")
TRYON_PANEL_OPS = ("move", "rotate", "drag", "fix", "unfix")


class TryOnMsg(Message, kw_only=True):
    """A try-on manipulation (Meng 2010 §6, ``couture.tryon``). ui, scripts ->
    solver, which applies it to its current state and re-solves from there
    (drape/coarse, drape/fine as usual). Key ``tryon``.

    ``start`` begins a try-on of the current drape (the placement before any):
    every seam sewn (``sewn``) or none (sequential sewing); the other ops
    start one with every seam sewn if none is running. ``move``: ``panel`` by
    ``vector`` [m]; ``rotate``: by ``angle`` [rad] about ``vector`` (an axis;
    zero: vertical) through the panel's centroid; ``drag``: slide the panel
    along the body by ``angle`` [rad] about its vertical axis and
    ``vector[1]`` [m] up it, kept outside the contact offset; ``fix`` /
    ``unfix``: pin / release ``panel``; ``sew`` / ``unsew``: ``seam`` (-1:
    the next unsewn / the last sewn; seams are numbered in drafted order).
    A new pattern generation ends the try-on.
    """

    TYPE: ClassVar[str] = "couture/tryon/v1"
    ARRAYS: ClassVar[dict[str, ArraySpec]] = {"vector": ArraySpec(F64, (3,), finite=True)}
    schema: str = "couture/tryon/v1"
    op_id: str = ""
    """identifier of this operation (drapes answering it are stamped after it)"""
    op: Literal["start", "move", "rotate", "drag", "fix", "unfix", "sew", "unsew"]
    panel: str = ""
    """panel name (move, rotate, drag, fix, unfix)"""
    vector: Array = msgspec.field(default_factory=lambda: Array.from_numpy(np.zeros(3)))
    """move: displacement [m]; rotate: axis; drag: [0, rise [m], 0]; shape (3,), float64"""
    angle: float = 0.0
    """rotate, drag: [rad]"""
    seam: int = -1
    """sew, unsew: seam index, -1 for the next / the last"""
    sewn: bool = True
    """start: every seam sewn (True) or none (False)"""

    def check(self) -> None:
        import math

        if not math.isfinite(self.angle):
            raise SchemaError(f"{self.TYPE}: field `$.angle`: {self.angle!r} is not finite")
        if self.op in TRYON_PANEL_OPS and not self.panel:
            raise SchemaError(f"{self.TYPE}: field `$.panel`: op {self.op!r} needs a panel")


class StatusMsg(Message, kw_only=True):
    """Health of one node. every node -> ui, supervisor, recorder. Key
    ``status/<node>``; presence itself is the liveliness token on the same key."""

    TYPE: ClassVar[str] = "couture/status/v1"
    schema: str = "couture/status/v1"
    node: str
    """node name, unique in the session"""
    kind: str = ""
    """'solver', 'remesher', 'sensitivity', 'ui', 'recorder', 'client', ..."""
    pid: int = 0
    """OS process id"""
    state: str = "running"
    """'starting', 'running', 'busy', 'stopping', 'error'"""
    uptime_s: float = 0.0
    """[s] since the node started"""
    rates: dict[str, float] = {}
    """events per second over the last status period [1/s], by name"""
    counters: dict[str, int] = {}
    """totals since start, by name (e.g. 'bad_messages', 'callback_errors')"""
    last_error: str = ""
    """last error text, '' if none"""
    ready: bool = True
    """the node serves requests at once (the sensitivity node: it holds the
    refactored equilibrium of the fine mesh held, so a press is predicted
    without waiting; a press before that is held until it is)"""
    ready_generation: int = -1
    """the design (the remesher's number) the node is ready for, -1 when not
    ready or not applicable"""
    ready_mesh_generation: int = -1
    """the fine mesh the node is ready for, -1 when not ready or not applicable"""
    regularization: str = ""
    """the sensitivity node: what its factorization added to the exact
    linearisation, in words ('none', or the bending or shift added, why, and
    its measured effect); '' when not applicable. An optional field added
    within v1: older readers ignore it"""
    nodes: dict[str, bool] = {}
    """the session's nodes as this node sees them by liveliness, name -> alive
    now (the ui: the list on its page, where a dead node stays listed as
    dead); {} from a node that does not watch them"""
    shown: str = ""
    """what a ui node has on screen, in the words of its status panel
    ('fine solve by solver-newton (newton), residual 3e-05, converged,
    generation 2'); '' elsewhere or before the first drape"""


class RejectedMsg(Message, kw_only=True):
    """A design a node refused, and why. remesher (drafting, validation,
    meshing), solver (a fabric or scene it cannot simulate, or a try-on op it
    cannot apply: ``op_id``) -> ui, clients. Key ``rejected``.

    Published at once, instead of meshes or drapes: a publisher waiting for
    the drape of this design stops waiting. The header's ``generation`` is
    the one the pattern asked for (a rejected design is given no number);
    ``design_id`` names the design exactly."""

    TYPE: ClassVar[str] = "couture/rejected/v1"
    schema: str = "couture/rejected/v1"
    node: str
    """the node that rejected it ('remesher', 'solver-kinetic', ...)"""
    design_id: str = ""
    """the rejected pattern's ``design_id`` ('' when it had none)"""
    element: str = ""
    """what is wrong, as a path into the design or an edit element id:
    'fabric.area_density', 'resolution.fine_vertices', 'param:length',
    'sloper', a stroke id, 'panel:segment', 'seam:...'; '' when unknown"""
    reason: str
    """the whole message: the element, the offending value and the allowed range"""
    name: str = ""
    """the pattern's name (file stem), if it had one"""
    source: str = ""
    """who published the pattern ('ui', 'client', 'replay', ...)"""
    op_id: str = ""
    """set when what was refused is a try-on op (``tryon``), not a design: that
    op's ``op_id`` (``element`` 'tryon.<op>'); the design and the drape on the
    solver stay as they were"""


class SolveRequestMsg(Message, kw_only=True):
    """Solve to equilibrium. any client (pattern adjustment, sweeps, scripts) ->
    a solver, through the ``solve/<solver>`` queryable; mirrored on
    ``solve/request`` so recordings hold it."""

    TYPE: ClassVar[str] = "couture/solve_request/v1"
    ARRAYS: ClassVar[dict[str, ArraySpec]] = {
        "x_warm": ArraySpec(F64, ("n", 3), finite=True, optional=True),
    }
    schema: str = "couture/solve_request/v1"
    request_id: str = ""
    """unique id, matches the result (filled by the bus if empty)"""
    mesh: MeshMsg | None = None
    """the mesh to solve on; None: the solver's latest mesh of mesh_generation/level"""
    mesh_generation: int = 0
    """when mesh is None: which mesh the solver must already hold"""
    level: Literal["coarse", "fine"] = "fine"
    """when mesh is None: which level"""
    design: Design | None = None
    """fabric/scene to use; None: the solver's current design"""
    x_warm: Array | None = None
    """warm start [m], shape (n, 3), float64; None: mesh x0"""
    tol: float = 1e-4
    """relative force residual to reach"""
    max_iters: int = 10_000
    """iteration cap"""
    max_seconds: float = 60.0
    """wall-time cap [s]"""
    solver: str = ""
    """solver wanted ('kinetic', 'newton', 'verlet'), '' for any"""


class SolveResultMsg(Message, kw_only=True):
    """Answer to a SolveRequestMsg. solver -> requester (query reply); mirrored
    on ``solve/result/<solver>``."""

    TYPE: ClassVar[str] = "couture/solve_result/v1"
    ARRAYS: ClassVar[dict[str, ArraySpec]] = {
        "x": ArraySpec(FLOAT_DTYPES, ("n", 3), finite=True, optional=True),
    }
    schema: str = "couture/solve_result/v1"
    request_id: str = ""
    """id of the request answered"""
    solver: str = ""
    """name of the solver that answered"""
    method: str = ""
    """'kinetic', 'newton', 'verlet'"""
    level: Literal["coarse", "fine"] = "fine"
    mesh_generation: int = 0
    x: Array | None = None
    """equilibrium (or last finite) positions [m], shape (n, 3); None when error is set"""
    residual: float = float("nan")
    """relative force residual at x"""
    iterations: int = 0
    wall_time_s: float = 0.0
    """[s]"""
    converged: bool = False
    diagnosis: str = ""
    """why it stopped if not converged"""
    error: str = ""
    """the request could not be run at all (bad mesh, unknown generation); x is None"""


ADJUST_EDITS = ("hem", "waist")
ADJUST_MAX_VERTICES = 5000
"""the largest mesh an adjustment request may ask for (each iteration solves it)"""
ADJUST_MAX_ITERS = 10


class AdjustMsg(Message, kw_only=True):
    """Adjust the pattern for a direct 3D edit of the drape (Bartle 2016,
    ``couture.adjust``). ui, scripts -> adjust node, which turns the edit of
    ``design``'s drape into a target garment, finds the pattern whose drape
    reproduces it (its solves go to the solver nodes), fits the design's
    sloper options to that pattern and publishes the result as a new
    ``pattern``; its progress and outcome on ``adjust/status``. Key ``adjust``.

    The header's ``generation`` is the design shown when the edit was made."""

    TYPE: ClassVar[str] = "couture/adjust/v1"
    schema: str = "couture/adjust/v1"
    request_id: str = ""
    """identifier of this request (its status messages carry it)"""
    edit: Literal["hem", "waist"]
    """'hem': the hem loop slides along the garment (length);
    'waist': the loop at the waist is offset from the body (fit)"""
    amount: float
    """[m] hem: length change, negative to shorten, positive to lengthen
    (the drape continued below its hem along its own flare);
    waist: girth change, positive to loosen"""
    design: Design = msgspec.field(default_factory=Design)
    """the design whose drape was edited"""
    design_id: str = ""
    """that design's identity (its pattern's ``design_id``)"""
    vertices: int = 0
    """coarse mesh size [vertices] of the adjustment's solves; 0: the node's default"""
    max_iters: int | None = None
    """fixed-point updates after the flattening (0..10); None: the adjust
    node's settings (``couture.adjust.settings.DEFAULTS.updates``, what
    ``couture adjust`` uses too)"""

    def check(self) -> None:
        import math

        if not math.isfinite(self.amount) or self.amount == 0.0:
            raise SchemaError(f"{self.TYPE}: field `$.amount`: {self.amount!r} m is not a finite nonzero length")
        if abs(self.amount) > 1.0:
            raise SchemaError(f"{self.TYPE}: field `$.amount`: {self.amount!r} m is beyond +-1 m")
        if self.vertices != 0 and not 50 <= self.vertices <= ADJUST_MAX_VERTICES:
            raise SchemaError(
                f"{self.TYPE}: field `$.vertices`: {self.vertices} outside 50..{ADJUST_MAX_VERTICES} (0: default)"
            )
        if self.max_iters is not None and not 0 <= self.max_iters <= ADJUST_MAX_ITERS:
            raise SchemaError(
                f"{self.TYPE}: field `$.max_iters`: {self.max_iters} outside 0..{ADJUST_MAX_ITERS} "
                "(or null: the adjust node's settings)"
            )


class AdjustStatusMsg(Message, kw_only=True):
    """Progress and outcome of one :class:`AdjustMsg`. adjust node -> ui,
    scripts. Key ``adjust/status``: ``running`` when it starts, ``iteration``
    after each re-simulated pattern, then ``done`` (the adjusted design went
    out as ``pattern`` with ``design_id``) or ``failed`` (``error`` says why;
    nothing was published, the current design stays)."""

    TYPE: ClassVar[str] = "couture/adjust_status/v1"
    schema: str = "couture/adjust_status/v1"
    request_id: str = ""
    """the request this answers"""
    node: str = ""
    """the adjust node that ran it"""
    state: Literal["running", "iteration", "done", "failed"] = "running"
    iteration: int = 0
    """fixed-point iterations done (0: the flattening)"""
    text: str = ""
    """one line for the designer (what happened, with numbers)"""
    error: str = ""
    """why it failed ('' unless state is 'failed')"""
    hausdorff_pct: float = float("nan")
    """done: [% of mannequin height] Hausdorff distance from the adjusted pattern's drape (the
    pattern the design was fitted to, after any gradient steps) to the target"""
    design_id: str = ""
    """done: the published adjusted design's identity"""
    options: dict[str, float] = {}
    """done: the sloper options the fit changed, name -> new value (SI)"""
    fit_rms_m: float = float("nan")
    """done: [m] RMS distance between the published design's pattern outline and the adjusted pattern's"""
    achieved_m: float = float("nan")
    """done: [m] the change measured on the published design's own coarse
    drape, in the request's terms (hem: length change, waist: girth change);
    a design says only what its sloper options can, so it may fall short of ``amount``"""
    stretch: float = float("nan")
    """done: mean stretch (Bartle's eq. 8, ``couture.adjust.geometry.stretch``) of the adjusted
    pattern's drape against the target"""
    solves: int = 0
    """done: re-simulated patterns the adjustment took (flattening, updates, gradient trials)"""
    goal_met: bool | None = None
    """done: whether the adjusted pattern met the goal (``couture.adjust.settings.GOAL``:
    Hausdorff, stretch, solves, seconds); None: not judged (recordings made before it)"""
    reasons: list[str] = []
    """done: one sentence per goal figure missed, with what was measured and where
    (``couture.adjust.verdict``); empty when the goal was met"""


MESSAGE_TYPES: tuple[type[Message], ...] = tuple(cls for cls in Message.__subclasses__() if cls.__module__ == __name__)
"""every message class defined in this module, in the order defined: a class is
registered by being defined (then its topic row in ``schemas.topics``)"""

REGISTRY: dict[str, type[Message]] = {cls.TYPE: cls for cls in MESSAGE_TYPES}
"""versioned type name -> class"""

_BY_BASE: dict[str, dict[int, type[Message]]] = {}
for _cls in MESSAGE_TYPES:
    _base, _v = _cls.TYPE.rsplit("/v", 1)
    _BY_BASE.setdefault(_base, {})[int(_v)] = _cls


# ---------------------------------------------------------------------------
# encode / decode / validate


class _Envelope(msgspec.Struct):
    schema: str
    version: int = 0


_ENVELOPE = msgspec.msgpack.Decoder(_Envelope)
_DECODERS = {name: msgspec.msgpack.Decoder(cls) for name, cls in REGISTRY.items()}
_TYPE_RE = re.compile(r"(couture/[a-z_]+)/v(\d+)")


def _enc_hook(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return Array.from_numpy(obj)
    if isinstance(obj, np.generic):
        return obj.item()
    raise NotImplementedError(f"cannot encode {type(obj).__name__}")


_ENCODER = msgspec.msgpack.Encoder(enc_hook=_enc_hook)


def encode(msg: Message) -> bytes:
    """Validate and serialize to msgpack (raises SchemaError on a bad message)."""
    validate(msg)
    return _ENCODER.encode(msg)


def peek_schema(data: bytes) -> str | None:
    """The ``schema`` field of a payload without decoding the rest, or None."""
    try:
        return _ENVELOPE.decode(data).schema
    except Exception:
        return None


M = TypeVar("M", bound=Message)


@overload
def decode(data: bytes | bytearray | memoryview, expected_type: type[M]) -> M: ...
@overload
def decode(data: bytes | bytearray | memoryview, expected_type: None = None) -> Message: ...
def decode(data: bytes | bytearray | memoryview, expected_type: type[Message] | None = None) -> Message:
    """Parse and validate a payload; raises SchemaError (only) naming schema and field."""
    try:
        env = _ENVELOPE.decode(data)
    except msgspec.ValidationError as e:
        raise SchemaError(f"unknown schema: {_field_msg(e)}") from None
    except Exception as e:
        raise SchemaError(f"unknown schema: not a msgpack map ({e})") from None
    m = _TYPE_RE.fullmatch(env.schema)
    if m is None or m.group(1) not in _BY_BASE:
        raise SchemaError(f"unknown schema {env.schema!r}; known: {', '.join(REGISTRY)}")
    base, version = m.group(1), int(m.group(2))
    versions = _BY_BASE[base]
    if version not in versions:
        raise SchemaError(
            f"{env.schema}: version {version} not accepted; accepted versions of {base}: "
            + ", ".join(f"v{v}" for v in sorted(versions))
        )
    if env.version != version:
        raise SchemaError(f"{env.schema}: field `$.version` is {env.version}, the schema name says {version}")
    cls = versions[version]
    if expected_type is not None and cls is not expected_type:
        raise SchemaError(f"{env.schema}: expected {expected_type.TYPE}")
    try:
        msg = _DECODERS[cls.TYPE].decode(data)
    except msgspec.ValidationError as e:
        raise SchemaError(f"{cls.TYPE}: {_field_msg(e)}") from None
    except Exception as e:
        raise SchemaError(f"{cls.TYPE}: malformed or truncated payload ({e})") from None
    validate(msg)
    return msg


def _field_msg(e: Exception) -> str:
    # msgspec says "Expected `int`, got `str` - at `$.seq`"; keep it, it names the path
    return str(e)


def validate(msg: Message, path: str = "$") -> None:
    """Check schema name, array dtypes/shapes/byte counts/finiteness, nested
    messages and type-specific rules. Raises SchemaError."""
    cls = type(msg)
    t = cls.TYPE
    if msg.schema != t:
        raise SchemaError(f"{t}: field `{path}.schema` is {msg.schema!r}, expected {t!r}")
    if msg.version != _version_of(t):
        raise SchemaError(f"{t}: field `{path}.version` is {msg.version}, expected {_version_of(t)}")
    dims: dict[str, tuple[int, str]] = {}
    for name, spec in cls.ARRAYS.items():
        fpath = f"{path}.{name}"
        a = getattr(msg, name)
        if a is None:
            if spec.optional:
                continue
            raise SchemaError(f"{t}: field `{fpath}` is required")
        if isinstance(a, np.ndarray):  # assigned after construction
            a = Array.from_numpy(a, spec.dtypes[0] if _wire_name_or_none(a.dtype) not in spec.dtypes else None)
            setattr(msg, name, a)
        if not isinstance(a, Array):
            raise SchemaError(f"{t}: field `{fpath}` must be an array, got {type(a).__name__}")
        problem = a.problem()
        if problem:
            raise SchemaError(f"{t}: field `{fpath}`: {problem}")
        if a.dtype not in spec.dtypes:
            raise SchemaError(
                f"{t}: field `{fpath}`: dtype {a.dtype} not allowed here (allowed: {', '.join(spec.dtypes)})"
            )
        if len(a.shape) != len(spec.shape):
            raise SchemaError(f"{t}: field `{fpath}`: shape {tuple(a.shape)} does not match {_shape_str(spec.shape)}")
        for size, want in zip(a.shape, spec.shape, strict=True):
            if isinstance(want, int):
                if size != want:
                    raise SchemaError(
                        f"{t}: field `{fpath}`: shape {tuple(a.shape)} does not match {_shape_str(spec.shape)}"
                    )
            elif want in dims and dims[want][0] != size:
                other = dims[want]
                raise SchemaError(
                    f"{t}: field `{fpath}`: shape {tuple(a.shape)} does not match {_shape_str(spec.shape)} "
                    f"with {want}={other[0]} from `{other[1]}`"
                )
            else:
                dims[want] = (size, fpath)
        if spec.finite and a.dtype in FLOAT_DTYPES:
            v = a.numpy()
            if not np.isfinite(v).all():
                bad = int(np.flatnonzero(~np.isfinite(v.ravel()))[0])
                raise SchemaError(f"{t}: field `{fpath}`: non-finite value (NaN/inf) at flat index {bad}")
    for name in cls.__struct_fields__:
        v = getattr(msg, name)
        if isinstance(v, Message):
            validate(v, f"{path}.{name}")
    msg.check()


def _shape_str(shape: tuple[int | str, ...]) -> str:
    return "(" + ", ".join(str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"


def json_schema(cls: type[Message]) -> bytes:
    """JSON Schema of a message type (stored in MCAP as the schema data)."""
    return msgspec.json.encode(msgspec.json.schema(cls))


__all__ = [
    "SchemaError",
    "Message",
    "AdjustMsg",
    "AdjustStatusMsg",
    "PatternMsg",
    "EditMsg",
    "MeshMsg",
    "PsiMsg",
    "DrapeMsg",
    "StatusMsg",
    "RejectedMsg",
    "SolveRequestMsg",
    "SolveResultMsg",
    "TryOnMsg",
    "MESSAGE_TYPES",
    "REGISTRY",
    "encode",
    "decode",
    "validate",
    "peek_schema",
    "json_schema",
    "ArraySpec",
]
