"""Scripting client: publish designs and edits, wait for drapes, ask solvers.

    with Client(session="s1", connect=["tcp/127.0.0.1:7447"]) as c:
        gen = c.publish_pattern("skirt.json")
        drape = c.wait_drape("fine", generation=gen, timeout=60)
        x = drape.x.numpy()

Timeouts raise :class:`TimeoutError` naming the topic that never answered and
the nodes that were (not) live, never a made-up result. A design that a node
refuses (``rejected`` topic: the remesher's validation, a solver's fabric
check) ends the wait for its drape at once with :class:`PatternRejected`,
which names the element and the reason.
"""

from __future__ import annotations

import contextlib
import os
import queue
import threading
import time
import uuid
from collections import OrderedDict
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any, Callable

import msgspec
import numpy as np

from couture.bus import DEFAULT_ENDPOINT, Bus, BusConfig, open_session
from couture.designs import GENERATION_LIMIT, OwnDesigns
from couture.mesh import GarmentMesh
from schemas.arrays import Array, as_array
from schemas.convert import mesh_to_msg
from schemas.design import Design
from schemas.messages import (
    DrapeMsg,
    EditMsg,
    MeshMsg,
    PatternMsg,
    RejectedMsg,
    SolveRequestMsg,
    SolveResultMsg,
    StatusMsg,
    TryOnMsg,
)

EXPECTED_PRODUCERS = {
    "mesh": "remesher",
    "drape/coarse": "solver-*",
    "drape/fine": "solver-*",
    "drape/predicted": "sensitivity",
}


class PatternRejected(ValueError):
    """A node (the remesher, a solver) rejected a design: ``element`` is the
    field or pattern element ('fabric.area_density', 'param:length'; '' when
    unknown), ``reason`` the whole message with the value and allowed range."""

    def __init__(
        self, generation: int, reason: str, node: str = "remesher", element: str = "", design_id: str = ""
    ) -> None:
        design = f" (design {design_id})" if design_id else ""
        super().__init__(f"{node} rejected pattern generation {generation}{design}: {reason}")
        self.generation = generation
        """the rejection's generation: the number the pattern asked for (the
        remesher gives a rejected design none), or the one its mesh carries (a solver)"""
        self.reason = reason
        self.node = node
        self.element = element
        self.design_id = design_id
        """the rejected design's identity (:meth:`schemas.messages.PatternMsg.identity`)"""

    @classmethod
    def from_msg(cls, msg: RejectedMsg) -> "PatternRejected":
        return cls(msg.generation, msg.reason, msg.node, msg.element, msg.design_id)


class TryOnRejected(ValueError):
    """A solver refused a try-on op (an unknown panel, a drag that cannot leave
    the body, ...): no drape will answer it; the drape stays as it was."""

    def __init__(self, op_id: str, reason: str, node: str = "") -> None:
        super().__init__(f"{node or 'solver'}: {reason}")
        self.op_id = op_id
        self.reason = reason
        self.node = node


def load_design(path: str | os.PathLike) -> Design:
    """Read a pattern JSON file (``couture/design/v1``); a top-level ``schema``
    key, if present, must name that type. A syntax error raises ValueError
    (:class:`couture.pattern.PatternError`) naming the file, line and column."""
    from couture.pattern.io import parse_json

    raw = parse_json(Path(path).read_bytes(), str(path))
    if isinstance(raw, dict) and "schema" in raw:
        if raw["schema"] != "couture/design/v1":
            raise ValueError(f"{path}: schema {raw['schema']!r} is not couture/design/v1")
        raw = raw.get("design", {k: v for k, v in raw.items() if k != "schema"})
    try:
        return msgspec.convert(raw, Design)
    except msgspec.ValidationError as e:
        raise ValueError(f"{path}: not a couture/design/v1 pattern: {e}") from None


class Client:
    """A bus participant for scripts and tests. Context manager.

    ``connect`` defaults to ``tcp/127.0.0.1:7447``, where ``couture up`` listens.
    In a secured session (``couture up --tls DIR``) pass ``tls=DIR``, a
    ``tls/`` endpoint and the ``name`` whose certificate ``DIR/<name>.pem`` the
    client presents (couture.bus.secure)."""

    def __init__(
        self,
        session: str = "default",
        connect: list[str] | None = None,
        *,
        listen: list[str] | None = None,
        name: str | None = None,
        bus: BusConfig | None = None,
        tls: str | None = None,
    ) -> None:
        self.cfg = bus or BusConfig(
            session=session,
            connect=list(connect) if connect is not None else [DEFAULT_ENDPOINT],
            listen=list(listen) if listen is not None else ["tcp/127.0.0.1:0"],
            tls=tls,
        )
        self.name = name or f"client-{os.getpid()}-{uuid.uuid4().hex[:6]}"
        self._cond = threading.Condition()
        self._drapes: dict[str, list[DrapeMsg]] = {"coarse": [], "fine": [], "predicted": []}
        self._meshes: dict[str, MeshMsg] = {}
        self._meshes_by_gen: dict[tuple[str, int], MeshMsg] = {}
        """(level, generation) -> latest mesh of that design (the newest 16 designs)"""
        self.status: dict[str, StatusMsg] = {}
        """latest status message per node name"""
        self._top = 0
        """the newest generation the remesher gave (seen on a mesh)"""
        self._asked = 0
        """the newest generation this client asked for"""
        self._own = OwnDesigns()
        self._rejected: OrderedDict[tuple[str, str], RejectedMsg] = OrderedDict()
        self._tryon_rejected: OrderedDict[str, RejectedMsg] = OrderedDict()
        """(design_id, or '#<generation>' when it had none; node) -> that node's first rejection of that design"""
        self._followers: list[queue.SimpleQueue] = []
        self._bus: Bus | None = None

    @property
    def bus(self) -> Bus:
        """The open session, between ``__enter__`` and ``__exit__``."""
        if self._bus is None:
            raise RuntimeError(f"{type(self).__name__} {self.name!r} is not open: use it in a `with` block")
        return self._bus

    def __enter__(self) -> "Client":
        self._bus = open_session(self.cfg, name=self.name)
        try:
            self.bus.declare_token(self.name)
            self._pattern_pub = self.bus.publisher("pattern", PatternMsg)
            self._edit_pub = self.bus.publisher("edit", EditMsg)
            self._tryon_pub = self.bus.publisher("tryon", TryOnMsg)
            self.bus.subscribe("drape/*", self._on_drape, DrapeMsg)
            self.bus.subscribe("mesh/*", self._on_mesh, MeshMsg)
            self.bus.subscribe("status/*", self._on_status, StatusMsg)
            self.bus.subscribe("rejected", self._on_rejected, RejectedMsg)
        except BaseException:
            self.bus.close()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.bus.close()

    # -- callbacks
    def _on_drape(self, msg: DrapeMsg) -> None:
        with self._cond:
            lst = self._drapes[msg.level]
            lst.append(msg)
            del lst[:-64]
            for q in self._followers:
                q.put(msg)
            self._cond.notify_all()

    def _on_mesh(self, msg: MeshMsg) -> None:
        with self._cond:
            self._meshes[msg.level] = msg
            if msg.generation < GENERATION_LIMIT:
                # only the remesher numbers designs; a pattern's number is a request
                self._top = max(self._top, msg.generation)
            self._meshes_by_gen[(msg.level, msg.generation)] = msg
            for key in sorted(self._meshes_by_gen, key=lambda k: k[1])[:-32]:
                del self._meshes_by_gen[key]
            if msg.design_id:
                self._own.meshed(msg.design_id, msg.generation)
            for q in self._followers:
                q.put(msg)
            self._cond.notify_all()

    def _on_status(self, msg: StatusMsg) -> None:
        with self._cond:
            self.status[msg.node] = msg
            for q in self._followers:
                q.put(msg)
            self._cond.notify_all()

    def _on_rejected(self, msg: RejectedMsg) -> None:
        with self._cond:
            if msg.op_id:  # a try-on op, not a design (wait_tryon)
                self._tryon_rejected[msg.op_id] = msg
                while len(self._tryon_rejected) > 256:
                    self._tryon_rejected.popitem(last=False)
                for q in self._followers:
                    q.put(msg)
                self._cond.notify_all()
                return
            key = (msg.design_id or f"#{msg.generation}", msg.node)
            if key not in self._rejected:
                self._rejected[key] = msg
                while len(self._rejected) > 256:
                    self._rejected.popitem(last=False)
            for q in self._followers:
                q.put(msg)
            self._cond.notify_all()

    # -- API
    def drapes(self, kind: str = "fine") -> list[DrapeMsg]:
        """The drapes of one kind received so far (the last 64), oldest first."""
        with self._cond:
            return list(self._drapes[kind])

    def live_nodes(self, timeout: float = 1.0) -> list[str]:
        return self.bus.live_nodes(timeout=timeout)

    def wait_nodes(self, nodes: list[str], timeout: float = 10.0) -> None:
        missing = self.bus.wait_nodes(nodes, timeout)
        if missing:
            raise TimeoutError(
                f"nodes {missing} not live on session {self.cfg.session} after {timeout:g} s "
                f"(live: {self.live_nodes() or 'none'})"
            )

    def wait_predictions_ready(
        self, timeout: float = 30.0, *, generation: int | None = None, node: str = "sensitivity"
    ) -> StatusMsg:
        """Wait until the sensitivity node's status says predictions are ready (it
        holds the refactored equilibrium of its fine mesh), for ``generation``
        (one this client asked for, or the remesher's number) when given, and
        return that status. A press sent before is not lost (the node holds it
        for a few seconds); this is for scripts that want the answer at once.
        Raises :class:`PatternRejected` when a node rejected that design (one
        this client published), TimeoutError naming the last status."""
        deadline = time.monotonic() + timeout

        def ok() -> StatusMsg | None:
            st = self.status.get(node)
            if st is None or not st.ready:
                return None
            if generation is None:
                return st
            target, exact = self._target(generation)
            if target is None:
                return None  # the remesher has not numbered our design yet
            return st if (st.ready_generation == target if exact else st.ready_generation >= target) else None

        with self._cond:
            while (st := ok()) is None:
                if (
                    generation is not None
                    and self._own.is_own(generation)
                    and (rej := self._rejection_locked(generation))
                ):
                    raise rej  # our design was rejected: it will never be ready
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                self._cond.wait(left)
            if st is not None:
                return st
            last = self.status.get(node)
        said = (
            "none"
            if last is None
            else f"ready={last.ready}, generation {last.ready_generation}, mesh generation {last.ready_mesh_generation}"
        )
        raise TimeoutError(
            f"predictions of node {node!r} not ready"
            + ("" if generation is None else f" for generation {generation}")
            + f" after {timeout:g} s (its last status: {said})"
        )

    def publish_pattern(
        self, design: Design | str | os.PathLike, *, name: str = "", wait_subscribers_s: float = 5.0
    ) -> int:
        """Publish a design (or a pattern JSON path) under a new ``design_id``;
        returns the generation it asks for (one more than the newest the
        remesher gave or this client asked for). The remesher numbers designs:
        when it gives another number, :meth:`wait_drape`, :meth:`follow_drape`
        and :meth:`generation_of` know it from its meshes."""
        if not isinstance(design, Design):
            name = name or Path(design).stem
            design = load_design(design)
        design_id = uuid.uuid4().hex
        with self._cond:
            gen = self._asked = max(self._asked, self._top) + 1
            self._own.add(design_id, gen)
        self._pattern_pub.wait_matching(wait_subscribers_s)
        self._pattern_pub.put(
            PatternMsg(design=design, generation=gen, design_id=design_id, source="client", name=name)
        )
        return gen

    def _target(self, generation: int | None) -> tuple[int | None, bool]:
        """(generation to match, exact): a generation this client asked for
        means exactly the one the remesher gave that design (None until known)."""
        if generation is not None and self._own.is_own(generation):
            return self._own.given(generation), True
        return generation, False

    def design_id_of(self, requested: int) -> str | None:
        """The design_id of this client's newest design that asked for ``requested``."""
        return self._own.design_of(requested)

    @property
    def current_generation(self) -> int:
        """The newest generation the remesher gave (0 before any mesh): the
        design it holds, which an edit without a generation is made on."""
        with self._cond:
            return self._top

    def generation_of(self, requested: int, timeout: float = 60.0) -> int:
        """The generation the remesher gave this client's design that asked for
        ``requested`` (waits for its first mesh). Raises TimeoutError."""
        if not self._own.is_own(requested):
            raise ValueError(f"generation {requested} was not asked for by this client")
        deadline = time.monotonic() + timeout
        with self._cond:
            while (g := self._own.given(requested)) is None:
                if (rej := self._rejection_locked(requested)) is not None:
                    raise rej
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(
                        f"no mesh of this client's design (generation {requested} asked for) "
                        f"within {timeout:g} s on session {self.cfg.session}"
                    )
                self._cond.wait(left)
            return g

    def mesh_of(self, generation: int, level: str = "fine") -> MeshMsg | None:
        """The latest mesh of ``level`` of the design the remesher numbered
        ``generation`` (one of the newest 16 designs), if seen."""
        with self._cond:
            return self._meshes_by_gen.get((level, generation))

    def send_edit(
        self,
        element: str,
        d: np.ndarray | list[float],
        *,
        phase: str = "drag",
        edit_id: str = "",
        dofs: list[str] | None = None,
        generation: int | None = None,
        **extra: object,
    ) -> EditMsg:
        """Send one edit message (press / drag / release); returns it (with its
        edit_id). ``generation``: the design it is made on (the remesher's
        number), by default the newest the remesher gave; receivers reject a
        press on any other design."""
        msg = EditMsg(
            edit_id=edit_id or uuid.uuid4().hex[:12],
            phase=phase,  # type: ignore[arg-type]
            element=element,
            dofs=list(dofs or ["x", "y"]),
            d=Array.from_numpy(np.asarray(d, np.float64)),
            generation=self.current_generation if generation is None else generation,
            **extra,  # type: ignore[arg-type]
        )
        self._edit_pub.put(msg)
        return msg

    def send_tryon(
        self,
        op: str,
        panel: str = "",
        *,
        vector: np.ndarray | list[float] | None = None,
        angle: float = 0.0,
        seam: int = -1,
        sewn: bool = True,
        op_id: str = "",
        generation: int | None = None,
    ) -> TryOnMsg:
        """Send one try-on op (``couture/tryon/v1``, couture.tryon: start, move,
        rotate, drag, fix, unfix, sew, unsew); returns it (with its op_id).
        The solver's drapes answering it carry the op_id as ``edit_id``
        (:meth:`wait_tryon`)."""
        msg = TryOnMsg(
            op_id=op_id or uuid.uuid4().hex[:12],
            op=op,  # type: ignore[arg-type]
            panel=panel,
            vector=Array.from_numpy(np.zeros(3) if vector is None else np.asarray(vector, np.float64)),
            angle=float(angle),
            seam=int(seam),
            sewn=bool(sewn),
            generation=self.current_generation if generation is None else generation,
        )
        self._tryon_pub.put(msg)
        return msg

    def wait_tryon(self, op_id: str, kind: str = "fine", timeout: float = 60.0) -> DrapeMsg:
        """The final drape of ``kind`` answering try-on op ``op_id``; raises
        :class:`TryOnRejected` as soon as a solver refuses the op, TimeoutError
        after ``timeout`` [s]."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                rej = self._tryon_rejected.get(op_id)
                if rej is not None:
                    raise TryOnRejected(op_id, rej.reason, rej.node)
                for m in reversed(self._drapes[kind]):
                    if m.final and m.edit_id == op_id:
                        return m
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f"no final drape/{kind} answering try-on {op_id} within {timeout:g} s")
                self._cond.wait(min(left, 0.1))

    def wait_drape(
        self,
        kind: str = "fine",
        generation: int | None = None,
        timeout: float = 60.0,
        *,
        converged: bool | None = None,
        final: bool | None = None,
    ) -> DrapeMsg:
        """For a generation this client's :meth:`publish_pattern` returned, the
        newest drape of ``kind`` ('fine', 'coarse', 'predicted') of exactly that
        design (the number the remesher gave it); for another generation, the
        newest with generation >= ``generation`` (any if None) among the numbers
        the remesher gave (a drape numbered above every mesh seen is foreign).
        Drapes that arrived since the client opened count. Raises
        :class:`PatternRejected` as soon as a node rejects that design (one
        this client published), TimeoutError naming what was missing after
        ``timeout`` [s]."""
        if kind not in self._drapes:
            raise ValueError(f"kind must be one of {list(self._drapes)}, got {kind!r}")
        deadline = time.monotonic() + timeout

        def find() -> DrapeMsg | None:
            target, exact = self._target(generation)
            if exact and target is None:
                return None  # the remesher has not numbered our design yet
            for m in reversed(self._drapes[kind]):
                if (
                    (m.generation == target if exact else (target is None or m.generation >= target))
                    and (exact or m.generation <= self._top)
                    and (converged is None or m.converged == converged)
                    and (final is None or m.final == final)
                ):
                    return m
            return None

        with self._cond:
            while (m := find()) is None:
                if (
                    generation is not None
                    and self._own.is_own(generation)
                    and (rej := self._rejection_locked(generation))
                ):
                    raise rej  # our design: its rejection is the answer (another's may be followed by a drape >= it)
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                self._cond.wait(left)
            if m is not None:
                return m
        raise self._timeout_error(kind, generation, timeout)

    def _timeout_error(self, kind: str, generation: int | None, timeout: float) -> TimeoutError:
        """A TimeoutError naming what was seen and which producers were (not) live."""
        with self._cond:
            meshes = {lvl: mm.generation for lvl, mm in self._meshes.items()}
            drapes = {k: (v[-1].generation if v else None) for k, v in self._drapes.items()}
        live = self.live_nodes(timeout=0.5)
        producer = EXPECTED_PRODUCERS[f"drape/{kind}"]
        hints = []
        if not meshes:
            hints.append(
                "no mesh/* message arrived: the remesher never answered"
                + ("" if "remesher" in live else " (remesher is not live)")
            )
        if producer.endswith("*") and not any(n.startswith(producer[:-1]) for n in live):
            hints.append(f"no {producer} node is live")
        elif not producer.endswith("*") and producer not in live:
            hints.append(f"{producer} is not live")
        what = f"generation >= {generation}"
        if generation is not None and self._own.is_own(generation):
            given = self._own.given(generation)
            what = f"this client's design {self._own.design_of(generation)} (asked for generation {generation}, " + (
                "not numbered yet: no mesh of it arrived)" if given is None else f"numbered {given})"
            )
        return TimeoutError(
            f"no drape/{kind} for {what} on session {self.cfg.session} within {timeout:g} s; "
            f"meshes seen (level: generation): {meshes or 'none'}; last drapes: {drapes}; live nodes: {live or 'none'}"
            + ("; " + "; ".join(hints) if hints else "")
        )

    def rejection(self, generation: int) -> PatternRejected | None:
        """A node's rejection of the design that asked for ``generation``, if
        one arrived. For a generation this client's :meth:`publish_pattern`
        returned, the rejection of exactly that design (by its ``design_id``):
        before the remesher numbered it, any node's; once numbered (the
        remesher took it), only one of the mesh it numbered (a solver's), so a
        re-sent or forged pattern under the same id is not taken for it."""
        with self._cond:
            return self._rejection_locked(generation)

    def rejections(self) -> list[RejectedMsg]:
        """Every rejection received so far (the last 256), oldest first."""
        with self._cond:
            return list(self._rejected.values())

    def _rejection_locked(self, generation: int) -> PatternRejected | None:
        own_id = self._own.design_of(generation)
        if own_id is not None:
            given = self._own.given(generation)
            msg = next(
                (m for (d, _), m in self._rejected.items() if d == own_id and (given is None or m.generation == given)),
                None,
            )
        else:  # not ours: a rejection of a design that asked for (or was numbered) that number
            msg = next((m for m in reversed(self._rejected.values()) if m.generation == generation), None)
        return None if msg is None else PatternRejected.from_msg(msg)

    def follow_drape(
        self, generation: int, timeout: float = 60.0, *, on_drape: Callable[[DrapeMsg], None] | None = None
    ) -> DrapeMsg:
        """Wait for the final drape/fine of exactly ``generation``: for a number
        this client's :meth:`publish_pattern` returned, of exactly that design
        (the number the remesher gave it, learnt from its meshes).

        Every drape/coarse and drape/fine of that design (progress snapshots
        and each level's final) is passed to ``on_drape`` as it arrives, in
        this thread, oldest first. Raises :class:`PatternRejected` as soon as
        a node rejects the design (the ``rejected`` message, sent the moment
        the remesher or a solver refuses it) and TimeoutError after
        ``timeout`` [s]."""
        q: queue.SimpleQueue = queue.SimpleQueue()
        with self._cond:
            backlog = sorted((m for lv in ("coarse", "fine") for m in self._drapes[lv]), key=lambda m: m.stamp_ns)
            for m in backlog:
                q.put(m)
            self._followers.append(q)
        deadline = time.monotonic() + timeout
        early: list[DrapeMsg] = []
        """drapes that arrived before the remesher's number for our design was known"""
        try:
            if (rej := self.rejection(generation)) is not None:
                raise rej
            while (left := deadline - time.monotonic()) > 0:
                try:
                    msg = q.get(timeout=left)
                except queue.Empty:
                    break
                if isinstance(msg, RejectedMsg):
                    if (rej := self.rejection(generation)) is not None:
                        raise rej
                    continue
                if isinstance(msg, StatusMsg):
                    continue
                target, exact = self._target(generation)
                if exact and target is None:
                    if isinstance(msg, DrapeMsg):
                        early.append(msg)
                        del early[:-256]
                    continue
                batch, early = [*early, msg], []
                for m in batch:
                    if not isinstance(m, DrapeMsg) or m.generation != target or m.level not in ("coarse", "fine"):
                        continue
                    if on_drape is not None:
                        on_drape(m)
                    if m.level == "fine" and m.final:
                        return m
        finally:
            with self._cond:
                self._followers.remove(q)
        raise self._timeout_error("fine", generation, timeout)

    def latest_mesh(self, level: str = "fine") -> MeshMsg | None:
        with self._cond:
            return self._meshes.get(level)

    def solve(
        self,
        mesh: GarmentMesh | MeshMsg,
        warm_start: np.ndarray | None = None,
        solver: str | None = None,
        *,
        tol: float = 1e-4,
        max_iters: int = 10_000,
        max_seconds: float = 60.0,
        timeout: float | None = None,
        design: Design | None = None,
    ) -> SolveResultMsg:
        """Solve ``mesh`` to equilibrium on a solver node (any if solver is None)."""
        return solve_on(
            self.bus,
            mesh,
            warm_start,
            solver,
            tol=tol,
            max_iters=max_iters,
            max_seconds=max_seconds,
            timeout=timeout,
            design=design,
        )


def solve_on(
    bus: Bus,
    mesh: GarmentMesh | MeshMsg,
    warm_start: np.ndarray | None = None,
    solver: str | None = None,
    *,
    tol: float = 1e-4,
    max_iters: int = 10_000,
    max_seconds: float = 60.0,
    timeout: float | None = None,
    design: Design | None = None,
) -> SolveResultMsg:
    """:meth:`Client.solve` on any open session (a node's own)."""
    mm = mesh if isinstance(mesh, MeshMsg) else mesh_to_msg(mesh)
    req = SolveRequestMsg(
        mesh=mm,
        x_warm=as_array(warm_start, "float64"),
        tol=tol,
        max_iters=max_iters,
        max_seconds=max_seconds,
        solver=solver or "",
        design=design,
        generation=mm.generation,
        level=mm.level,
    )
    return bus.solve(req, timeout=timeout if timeout is not None else max_seconds + 10.0)


class BusSolves:
    """What :class:`SolveFanout` needs of a :class:`Client` (``solve``,
    ``live_nodes``, ``cfg``), on a node's own open session."""

    def __init__(self, bus: Bus) -> None:
        self.bus, self.cfg = bus, bus.cfg

    def live_nodes(self, timeout: float = 1.0) -> list[str]:
        return self.bus.live_nodes(timeout=timeout)

    def solve(self, mesh: GarmentMesh | MeshMsg, warm_start: np.ndarray | None = None, solver: str | None = None, **kw):
        return solve_on(self.bus, mesh, warm_start, solver, **kw)


class SolveFanout:
    """Pattern adjustment's simulator on the bus (``couture.adjust``'s
    ``Simulate``): each solve of ``mesh`` with new rest positions goes as a
    ``solve`` request to the next of ``solvers`` (solver node names, round
    robin), so several solver processes share an adjustment's solves; a
    session's every solver is a black box behind the same request. ``solvers``
    None: every live ``solver-*`` node of the session. ``counts`` holds how
    many solves each node answered."""

    def __init__(
        self,
        client: Client | BusSolves,
        mesh: GarmentMesh,
        design: Design,
        solvers: list[str] | None = None,
        *,
        tol: float = 1e-4,
        max_seconds: float = 60.0,
    ) -> None:
        if solvers is None:
            solvers = sorted(n for n in client.live_nodes(timeout=1.0) if n.startswith("solver"))
            if not solvers:
                raise RuntimeError(f"no solver node is live on session {client.cfg.session}")
        if not solvers:
            raise ValueError("SolveFanout needs at least one solver node name")
        self.client, self.mesh, self.design = client, mesh, design
        self.solvers = list(solvers)
        self.tol, self.max_seconds = tol, max_seconds
        self.counts: dict[str, int] = {s: 0 for s in self.solvers}
        self.ready_timeout = 20.0
        """[s] how long a node that answers nothing at once (its queryable not declared yet) is asked again"""
        self._next = 0
        self._lock = threading.Lock()

    def __call__(self, X: np.ndarray, x_warm: np.ndarray):
        from couture.adjust.fixed_point import Simulated, with_rest

        with self._lock:
            name = self.solvers[self._next % len(self.solvers)]
            self._next += 1
        mesh = with_rest(self.mesh, X, x_warm)
        deadline = time.monotonic() + self.ready_timeout
        while True:
            asked = time.monotonic()
            try:
                res = self.client.solve(
                    mesh, x_warm, solver=name, tol=self.tol, max_seconds=self.max_seconds, design=self.design
                )
                break
            except TimeoutError:
                # a node's liveliness token comes up before its queryable: an
                # empty answer at once means "not serving yet", not "too slow"
                if time.monotonic() - asked > 1.0 or time.monotonic() > deadline:
                    raise
                time.sleep(0.2)
        if res.error or res.x is None:
            raise RuntimeError(f"solver {name} failed: {res.error or 'no positions in its result'}")
        with self._lock:
            self.counts[name] += 1
        return Simulated(
            x=np.asarray(res.x.numpy(), np.float64),
            residual=float(res.residual),
            converged=bool(res.converged),
            solver=res.solver or name,
            wall_time_s=float(res.wall_time_s),
            diagnosis=res.diagnosis,
        )


CONNECT_WAIT_S = 10.0
"""[s] how long :func:`solver_session` on a running session waits for its solver nodes to show"""


@contextlib.contextmanager
def solver_session(
    solvers: list[str], bus: BusConfig | None = None, *, log_file: str | None = None, timeout: float = 90.0
) -> Iterator[tuple[Client, list[str]]]:
    """A client and the names of the solver nodes it may ask: with ``bus.connect``,
    the live ``solver-*`` nodes of that session (``solvers`` names them when
    given); otherwise one solver node per entry of ``solvers`` (a registry name,
    couture.solvers.SOLVERS; a name twice gets two processes), started here under
    a supervisor (node logs to ``log_file``) and stopped on exit."""
    from couture import supervisor
    from couture.bus import free_port

    if bus is not None and bus.connect:
        with Client(bus=bus) as c:
            # a session just opened sees the nodes' liveliness tokens only once it has
            # connected: one query at once may find none (measured: 'live: []' on a
            # loaded machine with the nodes up), so wait up to CONNECT_WAIT_S for them
            wanted = [s if s.startswith("solver") else f"solver-{s}" for s in solvers]
            deadline = time.monotonic() + CONNECT_WAIT_S
            while True:
                live = sorted(n for n in c.live_nodes(timeout=1.0) if n.startswith("solver"))
                names = wanted or live
                missing = [n for n in names if n not in live]
                if (names and not missing) or time.monotonic() >= deadline:
                    break
                time.sleep(0.1)
            if missing or not names:
                raise RuntimeError(
                    f"solver nodes {missing or 'any'} not live on session {bus.session} after {CONNECT_WAIT_S:g} s "
                    f"(live: {live})"
                )
            yield c, names
        return
    if not solvers:
        raise ValueError("solver_session needs at least one solver to start (or a bus to connect to)")
    names, specs = [], []
    for i, s in enumerate(solvers):
        name = f"solver-{s}" if solvers.count(s) == 1 else f"solver-{s}{i}"
        names.append(name)
        specs.append(supervisor.NodeSpec(name, "nodes.solver", ["--solver", s]))
    cfg = bus or BusConfig(session=f"adjust{int(time.time() * 1000) % 10**8}")
    if not cfg.listen:
        cfg = replace(cfg, listen=[f"tcp/127.0.0.1:{free_port()}"])
    with supervisor.Supervisor(supervisor.SupervisorConfig(bus=cfg, nodes=specs, child_log=log_file)) as sup:
        with Client(bus=sup.child_bus) as c:
            c.wait_nodes(names, timeout=timeout)
            yield c, names


def adjust_on_bus(
    client: Client, names: list[str], design: Design, edit: str, amount: float, **kw: Any
) -> tuple[Any, dict[str, int]]:
    """Pattern adjustment (couture.adjust.pipeline.run_case: ``edit`` 'hem' or
    'waist' by ``amount`` [m], ``kw`` its options) with every solve a request to
    the solver nodes ``names`` (:class:`SolveFanout`, ``max_seconds`` per solve,
    default 60 s). Returns the case and how many solves each node answered."""
    from couture.adjust.pipeline import run_case

    fans: list[SolveFanout] = []
    max_seconds = kw.pop("max_seconds", 60.0)

    def simulate_for(mesh: GarmentMesh) -> SolveFanout:
        fans.append(SolveFanout(client, mesh, design, names, max_seconds=max_seconds))
        return fans[-1]

    case = run_case(design, edit, amount, simulate_for, **kw)
    return case, (fans[-1].counts if fans else {})


def fit_on_bus(
    client: Client,
    names: list[str],
    design: Design,
    case: Any,
    *,
    vertices: int,
    max_seconds: float = 60.0,
    progress: Callable[[str, int, str], None] | None = None,
) -> Any:
    """The design the adjust node would publish for ``case`` (an
    :func:`adjust_on_bus` result of ``design`` at ``vertices``):
    :func:`couture.adjust.service.fit_design`, its drapes on the solver nodes
    ``names``. Returns its ``AdjustOutcome``; raises ValueError when no sloper
    option can express the adjusted pattern."""
    from couture.adjust.service import fit_design

    def simulate_for(mesh: GarmentMesh) -> SolveFanout:
        return SolveFanout(client, mesh, design, names, max_seconds=max_seconds)

    return fit_design(design, case, simulate_for, vertices=vertices, progress=progress)
