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

import os
import queue
import threading
import time
import uuid
from collections import OrderedDict
from pathlib import Path
from typing import Callable

import msgspec
import numpy as np

from couture.bus import DEFAULT_ENDPOINT, Bus, BusConfig, open_session
from couture.designs import OwnDesigns
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

    def __init__(self, generation: int, reason: str, node: str = "remesher", element: str = "") -> None:
        super().__init__(f"{node} rejected pattern generation {generation}: {reason}")
        self.generation = generation
        self.reason = reason
        self.node = node
        self.element = element

    @classmethod
    def from_msg(cls, msg: RejectedMsg) -> "PatternRejected":
        return cls(msg.generation, msg.reason, msg.node, msg.element)


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

    ``connect`` defaults to ``tcp/127.0.0.1:7447``, where ``couture up`` listens."""

    def __init__(
        self,
        session: str = "default",
        connect: list[str] | None = None,
        *,
        listen: list[str] | None = None,
        name: str | None = None,
        bus: BusConfig | None = None,
    ) -> None:
        self.cfg = bus or BusConfig(
            session=session,
            connect=list(connect) if connect is not None else [DEFAULT_ENDPOINT],
            listen=list(listen) if listen is not None else ["tcp/127.0.0.1:0"],
        )
        self.name = name or f"client-{os.getpid()}-{uuid.uuid4().hex[:6]}"
        self._cond = threading.Condition()
        self._drapes: dict[str, list[DrapeMsg]] = {"coarse": [], "fine": [], "predicted": []}
        self._meshes: dict[str, MeshMsg] = {}
        self.status: dict[str, StatusMsg] = {}
        """latest status message per node name"""
        self._seen_generation = 0
        self._own = OwnDesigns()
        self._asked: OrderedDict[int, str] = OrderedDict()
        """generation asked for -> design_id of this client's newest design that asked for it"""
        self._rejected: OrderedDict[tuple[str, str], RejectedMsg] = OrderedDict()
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
            self.bus.subscribe("drape/*", self._on_drape, DrapeMsg)
            self.bus.subscribe("mesh/*", self._on_mesh, MeshMsg)
            self.bus.subscribe("pattern", self._on_pattern, PatternMsg)
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
            if msg.design_id:
                self._own.meshed(msg.design_id, msg.generation)
            self._seen_generation = max(self._seen_generation, msg.generation)
            self._cond.notify_all()

    def _on_status(self, msg: StatusMsg) -> None:
        with self._cond:
            self.status[msg.node] = msg
            for q in self._followers:
                q.put(msg)

    def _on_rejected(self, msg: RejectedMsg) -> None:
        with self._cond:
            key = (msg.design_id or f"#{msg.generation}", msg.node)
            if key not in self._rejected:
                self._rejected[key] = msg
                while len(self._rejected) > 256:
                    self._rejected.popitem(last=False)
            for q in self._followers:
                q.put(msg)
            self._cond.notify_all()

    def _on_pattern(self, msg: PatternMsg) -> None:
        with self._cond:
            self._seen_generation = max(self._seen_generation, msg.generation)

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

    def publish_pattern(
        self, design: Design | str | os.PathLike, *, name: str = "", wait_subscribers_s: float = 5.0
    ) -> int:
        """Publish a design (or a pattern JSON path) under a new ``design_id``;
        returns the generation it asks for (one more than the newest seen on
        the bus, at least 1). The remesher numbers designs: when it gives
        another number, :meth:`wait_drape` and :meth:`generation_of` know."""
        if not isinstance(design, Design):
            name = name or Path(design).stem
            design = load_design(design)
        design_id = uuid.uuid4().hex
        with self._cond:
            gen = self._seen_generation + 1
            self._seen_generation = gen
            self._own.add(design_id, gen)
            self._asked[gen] = design_id
            self._asked.move_to_end(gen)
            while len(self._asked) > 256:
                self._asked.popitem(last=False)
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
        """Send one edit message (press / drag / release); returns it (with its edit_id)."""
        msg = EditMsg(
            edit_id=edit_id or uuid.uuid4().hex[:12],
            phase=phase,  # type: ignore[arg-type]
            element=element,
            dofs=list(dofs or ["x", "y"]),
            d=Array.from_numpy(np.asarray(d, np.float64)),
            generation=self._seen_generation if generation is None else generation,
            **extra,  # type: ignore[arg-type]
        )
        self._edit_pub.put(msg)
        return msg

    def wait_drape(
        self,
        kind: str = "fine",
        generation: int | None = None,
        timeout: float = 60.0,
        *,
        converged: bool | None = None,
        final: bool | None = None,
    ) -> DrapeMsg:
        """The newest drape of ``kind`` ('fine', 'coarse', 'predicted') with
        generation >= ``generation`` (any if None) that arrives or has arrived
        since the client opened; for a generation this client's
        :meth:`publish_pattern` returned, a drape of exactly that design.
        Raises :class:`PatternRejected` as soon as a node rejects that design
        (one this client published), TimeoutError naming what was missing
        after ``timeout`` [s]."""
        if kind not in self._drapes:
            raise ValueError(f"kind must be one of {list(self._drapes)}, got {kind!r}")
        deadline = time.monotonic() + timeout

        def find() -> DrapeMsg | None:
            target, exact = self._target(generation)
            if exact and target is None:
                return None  # the remesher has not numbered our design yet
            for m in reversed(self._drapes[kind]):
                if (
                    (target is None or (m.generation == target if exact else m.generation >= target))
                    and (converged is None or m.converged == converged)
                    and (final is None or m.final == final)
                ):
                    return m
            return None

        with self._cond:
            while (m := find()) is None:
                if generation is not None and generation in self._asked and (rej := self._rejection_locked(generation)):
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
        return TimeoutError(
            f"no drape/{kind} for generation >= {generation} on session {self.cfg.session} within {timeout:g} s; "
            f"meshes seen (level: generation): {meshes or 'none'}; last drapes: {drapes}; live nodes: {live or 'none'}"
            + ("; " + "; ".join(hints) if hints else "")
        )

    def rejection(self, generation: int) -> PatternRejected | None:
        """A node's rejection of the design that asked for ``generation``, if
        one arrived: for a generation this client's :meth:`publish_pattern`
        returned, the rejection of exactly that design (by ``design_id``)."""
        with self._cond:
            return self._rejection_locked(generation)

    def rejections(self) -> list[RejectedMsg]:
        """Every rejection received so far (the last 256), oldest first."""
        with self._cond:
            return list(self._rejected.values())

    def _rejection_locked(self, generation: int) -> PatternRejected | None:
        design_id = self._asked.get(generation)
        if design_id is not None:
            msg = next((m for (d, _), m in self._rejected.items() if d == design_id), None)
        else:  # not ours: a rejection of a design that asked for that number
            msg = next((m for m in reversed(self._rejected.values()) if m.generation == generation), None)
        return None if msg is None else PatternRejected.from_msg(msg)

    def follow_drape(
        self, generation: int, timeout: float = 60.0, *, on_drape: Callable[[DrapeMsg], None] | None = None
    ) -> DrapeMsg:
        """Wait for the final drape/fine of exactly ``generation``.

        Every drape/coarse and drape/fine of that generation (progress
        snapshots and each level's final) is passed to ``on_drape`` as it
        arrives, in this thread, oldest first. Raises :class:`PatternRejected`
        as soon as a node rejects the design (the ``rejected`` message, sent
        the moment the remesher or a solver refuses it) and TimeoutError
        after ``timeout`` [s]."""
        q: queue.SimpleQueue = queue.SimpleQueue()
        with self._cond:
            backlog = sorted((m for lv in ("coarse", "fine") for m in self._drapes[lv]), key=lambda m: m.stamp_ns)
            for m in backlog:
                q.put(m)
            self._followers.append(q)
        deadline = time.monotonic() + timeout
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
                if msg.generation != generation or msg.level not in ("coarse", "fine"):
                    continue
                if on_drape is not None:
                    on_drape(msg)
                if msg.level == "fine" and msg.final:
                    return msg
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
        return self.bus.solve(req, timeout=timeout if timeout is not None else max_seconds + 10.0)
