"""The ui node: a thin adapter between the bus and :class:`couture.ui.CoutureUI`.

Messages in → ``CoutureUI.show_*``/``set_*`` (which only store the newest value
and return: Zenoh callback threads never wait on drawing); user actions →
messages out (``pattern`` on every design change, ``edit`` on every drag phase).

Design identity (:class:`couture.designs.ShownDesign`): the remesher numbers
designs and its meshes echo each design's id with its number, so the UI
learns the number of the design it shows and its edits carry it; another
publisher's design is shown once the remesher has numbered it (a rejected one
never is); a drape numbered above every mesh seen is held back until its mesh
arrives (a foreign number can never hide later drapes), and another client's
edit on a design not shown is not previewed. Each is logged and counted
(``held_drapes``, ``stale_edits``, ``foreign_edits``, ``foreign_meshes``).

Also here, because they need the bus: which solver's drapes are shown (the
"solver" dropdown: drapes of other ``solver-*`` nodes are kept but not
drawn), the status notes that say what the pipeline can do right now (no
sensitivity node: no predictions while dragging), and the record toggle
(with no recorder node live it runs ``python -m couture.recording`` on this
node's bus and stops it with SIGINT so the MCAP file is finalized).
"""

from __future__ import annotations

import logging
import signal
import subprocess
import sys
import threading
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from couture.bus import BusConfig, Node
from couture.designs import ShownDesign, judge
from couture.ui import CoutureUI, UIConfig
from couture.ui.gestures import Edit
from couture.ui.status import describe_frame
from schemas.arrays import Array
from schemas.convert import msg_to_mesh
from schemas.design import Design
from schemas.messages import (
    AdjustMsg,
    AdjustStatusMsg,
    DrapeMsg,
    EditMsg,
    MeshMsg,
    PatternMsg,
    RejectedMsg,
    StatusMsg,
    TryOnMsg,
)

log = logging.getLogger("couture.ui.node")


def _load_design(path: str) -> Design:
    from couture.client import load_design

    return load_design(path)


@dataclass
class Config:
    bus: BusConfig = field(default_factory=BusConfig)
    name: str = "ui"
    """node name, unique in the session (liveliness key status/<name>)"""
    host: str = "127.0.0.1"
    """viser binds here (loopback by default)"""
    port: int = 8080
    """the combined page (what users open); the 3D view is port + 1, the pattern view port + 2; a taken port
    moves the page to the next free one (port + 3, ...), and the URL printed says where"""
    export_dir: Path = Path("out/exports")
    """where exports are written"""
    record_dir: Path = Path("out/recordings")
    """where the record toggle writes session-<time>.mcap (when no recorder node runs)"""
    design: Design | None = field(default=None, metadata={"parse": _load_design})
    """initial design, read from a pattern JSON file (couture/design/v1) when the
    session has none yet (None: the default skirt); published once at start"""
    publish_initial: bool = True
    """publish the initial design once at start when no pattern came from the session"""


class UIAdapter:
    """Wires one CoutureUI to one bus. Separate from :func:`main` so tests can
    drive it with their own Node."""

    def __init__(
        self,
        node: Node,
        ui: CoutureUI,
        name: str,
        *,
        bus_config: BusConfig | None = None,
        record_dir: Path = Path("out/recordings"),
    ):
        self.node, self.ui, self.name = node, ui, name
        self.bus_config = bus_config or BusConfig()
        self.record_dir = Path(record_dir)
        self.recorder: subprocess.Popen | None = None
        self.record_path: Path | None = None
        self.live: dict[str, bool] = {}
        self._last: dict[tuple[str, str], DrapeMsg] = {}
        """(solver, level) -> newest drape, to re-show on a solver switch"""
        self._lock = threading.Lock()
        bus = node.bus
        self.pattern_pub = bus.publisher("pattern", PatternMsg)
        self.edit_pub = bus.publisher("edit", EditMsg)
        self.tryon_pub = bus.publisher("tryon", TryOnMsg)
        self.adjust_pub = bus.publisher("adjust", AdjustMsg)
        self._adjust_ids: set[str] = set()
        """the adjust requests this ui sent (their status is shown)"""
        self._own_edits: set[str] = set()
        self._drape_gen: dict[tuple[str, str], int] = {}
        self.view = ShownDesign()
        """which design is shown and the remesher's numbers (under ``_lock``)"""
        self._early: dict[tuple[str, str], DrapeMsg] = {}
        """(solver, level) -> newest drape numbered above every mesh seen, held until its mesh arrives"""
        self.seen_pattern = False
        self._newest_mesh: tuple[int, str] = (0, "")
        """(send time, design identity) of the newest new mesh: a rejection of
        another design older than it is history (under ``_lock``)"""
        self._rejected: tuple[int, str] | None = None
        """(send time, design identity) of the rejection shown (under ``_lock``)"""
        ui.on_design_changed = self.publish_design
        ui.on_edit = self.publish_edit
        ui.on_tryon = self.publish_tryon
        ui.on_adjust = self.publish_adjust
        ui.on_solver_selected = self.select_solver
        ui.on_record = self.record
        bus.subscribe("pattern", self.on_pattern)
        bus.subscribe("edit", self.on_edit)
        bus.subscribe("mesh/*", self.on_mesh)
        bus.subscribe("drape/*", self.on_drape)
        bus.subscribe("status/*", self.on_status)
        bus.subscribe("rejected", self.on_rejected)
        bus.subscribe("adjust/status", self.on_adjust_status)
        bus.watch_nodes(self.on_liveliness)
        self._update_notes()
        node.status_fields = self.status_view

    def status_view(self) -> dict[str, object]:
        """What this node's status says it shows: the nodes it lists (alive or
        dead) and the drape on screen."""
        frame = self.ui.on_screen
        return {"nodes": dict(self.live), "shown": describe_frame(frame) if frame is not None else ""}

    # -- out
    def publish_design(self, design: Design) -> None:
        design_id = uuid.uuid4().hex
        with self._lock:
            generation = self.view.request()
            self.view.committed(design_id)
        self.ui.generation = generation
        self.pattern_pub.put(PatternMsg(design=design, source=self.name, generation=generation, design_id=design_id))
        self.node.count("pattern_out")

    def publish_edit(self, edit: Edit) -> None:
        self._own_edits.add(edit.edit_id)
        if len(self._own_edits) > 1000:
            self._own_edits.clear()
        with self._lock:
            generation = self.view.edit_generation()
        self.edit_pub.put(edit_msg(edit, generation))
        self.node.count("edit_out")

    def publish_tryon(self, op: dict) -> None:
        """A Try-on button: one ``couture/tryon/v1`` on the design shown."""
        with self._lock:
            generation = self.view.edit_generation()
        self.tryon_pub.put(tryon_msg(op, generation))
        self.node.count("tryon_out")

    def publish_adjust(self, loop: str, amount: float) -> str:
        """The Adjust pattern folder's request: one ``couture/adjust/v1`` for the
        design shown; raises (the folder shows it) when no adjust node is live
        or the request is malformed."""
        adjusters = sorted(n for n, alive in self.live.items() if alive and n.startswith("adjust"))
        if not adjusters:
            raise RuntimeError(
                "no adjust node is live in this session (couture up starts one; or run python -m nodes.adjust)"
            )
        with self._lock:
            generation = self.view.edit_generation()
            design_id = self.view.shown_id or ""
        msg = adjust_msg(loop, amount, self.ui.design, design_id, generation)
        self._adjust_ids.add(msg.request_id)
        self.adjust_pub.put(msg)  # validates: a malformed request raises SchemaError naming the field
        self.node.count("adjust_out")
        log.info("adjust request %s: %s %+.3f m to %s", msg.request_id, loop, amount, adjusters)
        return msg.request_id

    def on_adjust_status(self, msg: AdjustStatusMsg) -> None:
        if msg.request_id not in self._adjust_ids:
            return  # another client's request
        self.ui.show_adjust_status(msg.state, msg.iteration, msg.text, msg.error, msg.goal_met)

    # -- in (Zenoh threads: store and return)
    def on_pattern(self, msg: PatternMsg) -> None:
        self.seen_pattern = True
        if msg.source == self.name:
            return  # our own echo
        with self._lock:
            adopt = self.view.pattern(msg.identity(), msg.design)
            shown = self.view.shown_generation
        self._adopt(adopt, shown)

    def _adopt(self, design: Design | None, generation: int | None) -> None:
        """Show another publisher's design the remesher has numbered ``generation``."""
        if design is None or generation is None:
            return
        log.info("showing another publisher's design, generation %d", generation)
        self.ui.generation = generation
        self.ui.set_design(design)

    def on_edit(self, msg: EditMsg) -> None:
        if msg.edit_id in self._own_edits or msg.picked_vertex >= 0:
            return  # our own, or a 3D tug (its d is in pixels: nothing to move in 2D)
        with self._lock:
            shown = self.view.shown_generation
        verdict = "current" if shown is None else judge(msg.generation, shown)
        if verdict != "current":
            if msg.phase == "press":
                self.node.count(f"{verdict}_edits")
                log.info(
                    "edit %s on generation %d not previewed: generation %d is shown (%s)",
                    msg.edit_id,
                    msg.generation,
                    shown,
                    verdict,
                )
            return
        self.ui.preview_remote_edit(msg.element, msg.d.numpy())

    def on_mesh(self, msg: MeshMsg) -> None:
        clear = False
        with self._lock:
            accepted, adopt = self.view.meshed(msg.design_id, msg.generation)
            if not accepted:
                self.node.count("foreign_meshes")
                log.warning(
                    "mesh/%s of generation %d ignored: not a number the remesher gives", msg.level, msg.generation
                )
                return
            shown = self.view.shown_generation
            if shown is not None and msg.design_id == self.view.shown_id:
                self.ui.generation = shown
            early = [m for m in self._early.values() if m.generation <= self.view.top]
            for m in early:
                del self._early[(m.solver, m.level)]
            self._newest_mesh = (msg.stamp_ns, msg.design_id)
            rej = self._rejected
            if rej is not None and msg.stamp_ns > rej[0] and not _same_design(msg.design_id, rej[1]):
                self._rejected, clear = None, True  # a later design was meshed
        if clear:
            self.ui.set_rejection("")
        self._adopt(adopt, shown)
        self.ui.show_mesh(msg_to_mesh(msg))
        for m in early:
            self.on_drape(m)

    def on_drape(self, msg: DrapeMsg) -> None:
        key = (msg.solver, msg.level)
        with self._lock:
            if msg.generation > self.view.top:
                # no mesh of that number yet: its mesh is on the way, or the number is foreign
                if key not in self._early:
                    self.node.count("held_drapes")
                    log.info(
                        "drape/%s of generation %d from %r held: the newest mesh is of generation %d",
                        msg.level,
                        msg.generation,
                        msg.solver,
                        self.view.top,
                    )
                self._early[key] = msg
                return
            # drop a drape older than one already shown from that producer at
            # that level (history can arrive out of order)
            if msg.generation < self._drape_gen.get(key, -1):
                return
            self._drape_gen[key] = msg.generation
            self._last[key] = msg
        chosen = self.ui.selected_solver
        if msg.solver and chosen != "any" and msg.solver != chosen:
            self.node.count("drape_other_solver")
            return
        self._show(msg)

    def _show(self, msg: DrapeMsg) -> None:
        self.ui.show_drape(
            msg.x.numpy(),
            msg.level,
            msg.method,
            residual=msg.residual,
            error_estimate=msg.error_estimate,
            error_estimate_m=msg.error_estimate_m,
            generation=msg.generation,
            solver=msg.solver,
            converged=msg.converged if msg.solver else None,
            diagnosis=msg.diagnosis,
            final=msg.final,
            edit_id=msg.edit_id,
        )
        self.node.count("drape_in")

    def select_solver(self, name: str) -> None:
        """Show ``name``'s newest drape at once (fine, else coarse)."""
        log.info("solver selected: %s", name)
        with self._lock:
            mine = [m for (s, lv), m in self._last.items() if s and (name == "any" or s == name)]
        if mine:
            best = max(mine, key=lambda m: (m.generation, m.level == "fine", m.stamp_ns))
            self._show(best)
        self._update_notes()

    def on_liveliness(self, node: str, alive: bool) -> None:
        self.live[node] = alive
        self.ui.set_live_nodes({node: alive})
        self._update_notes()

    def _update_notes(self) -> None:
        live = {n for n, a in self.live.items() if a}
        notes = []
        if not any(n.startswith("sensitivity") for n in live):
            notes.append(
                "Predictions are off (no sensitivity node is live): while dragging the pattern moves; "
                "the solver's drape is shown after release."
            )
        solvers = sorted(n for n in live if n.startswith("solver"))
        if not solvers:
            notes.append("No solver node is live: the last drape stays on screen.")
        chosen = self.ui.selected_solver
        if chosen != "any" and chosen not in live:
            notes.append(f"{chosen} is not live: its last drape stays on screen (choose another solver).")
        elif chosen != "any" and len(solvers) > 1:
            others = ", ".join(s for s in solvers if s != chosen)
            notes.append(f"Showing {chosen}'s drapes only ({others} also running).")
        self.ui.set_status_notes(notes)

    # -- record toggle
    def record(self, on: bool) -> None:
        if on:
            self.start_recording()
        else:
            self.stop_recording()

    def recorder_args(self, out: Path) -> list[str]:
        """``python -m couture.recording`` on this node's bus: the same session,
        connecting where this node connects (or to where it listens)."""
        cfg = self.bus_config
        connect = list(cfg.connect) or [e for e in cfg.listen if not e.endswith(":0")]
        rec = BusConfig(
            session=cfg.session,
            connect=connect,
            listen=["tcp/127.0.0.1:0"],
            mode="peer",
            config_file=cfg.config_file,
            multicast=cfg.multicast,
        )
        return [
            sys.executable,
            "-m",
            "couture.recording",
            "--out",
            str(out),
            "--quiet",
            "--name",
            f"{self.name}-recorder",
            *rec.to_args(),
        ]

    def start_recording(self) -> Path | None:
        if self.recorder is not None and self.recorder.poll() is None:
            return self.record_path
        nodes = [n for n, a in self.live.items() if a and n.startswith("recorder")]
        if nodes:
            self.ui.set_record_note(f"`{nodes[0]}` already records this session (see its --out file).", on=True)
            return None
        self.record_dir.mkdir(parents=True, exist_ok=True)
        path = (self.record_dir / f"session-{time.strftime('%Y%m%d-%H%M%S')}.mcap").resolve()
        self.recorder = subprocess.Popen(self.recorder_args(path), stdin=subprocess.DEVNULL, start_new_session=True)
        self.record_path = path
        log.info("recording to %s (pid %d)", path, self.recorder.pid)
        self.ui.set_record_note(f"recording to `{path}`", on=True)
        return path

    def stop_recording(self, timeout: float = 10.0) -> Path | None:
        proc, path = self.recorder, self.record_path
        if proc is None:
            return None
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)  # the recorder finalizes the MCAP file (summary, index)
            try:
                proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                proc.terminate()
                try:
                    proc.wait(timeout=3.0)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
        self.recorder = None
        log.info("recording stopped: %s", path)
        self.ui.set_record_note(f"recorded `{path}`", on=False)
        return path

    def close(self) -> None:
        self.stop_recording()

    def on_rejected(self, msg: RejectedMsg) -> None:
        """A design a node refused: shown at the top of the status until a
        later mesh of another design arrives. A solver's rejection of the
        design on screen (the remesher meshed it) is shown even when its
        other level's mesh came later. A refused try-on op is shown in the
        try-on folder; the design stays accepted."""
        if msg.op_id:
            self.ui.set_tryon_note(f"{msg.node}: {msg.reason}")
            self.node.count("rejected_in")
            return
        with self._lock:
            mesh_ns, mesh_id = self._newest_mesh
            if (msg.stamp_ns < mesh_ns and not _same_design(msg.design_id, mesh_id)) or (
                self._rejected is not None and msg.stamp_ns < self._rejected[0]
            ):
                return  # history from before the mesh (or the rejection) on screen
            self._rejected = (msg.stamp_ns, msg.design_id)
        if msg.name:
            who = f"design {msg.name!r}"
        elif msg.design_id:
            who = f"design {msg.design_id} (generation {msg.generation})"
        else:
            who = f"generation {msg.generation}"
        src = f" from {msg.source}" if msg.source else ""
        self.ui.set_rejection(f"{msg.node} rejected {who}{src}: {msg.reason}")
        self.node.count("rejected_in")

    def on_status(self, msg: StatusMsg) -> None:
        state = msg.state
        if msg.regularization and msg.regularization != "none":
            state += f" (regularized: {msg.regularization})"
        self.ui.set_node_status(msg.node, kind=msg.kind, state=state, rates=msg.rates, last_error=msg.last_error)


def _same_design(a: str, b: str) -> bool:
    """Both identities known and equal ('' is no identity: never the same)."""
    return bool(a) and a == b


def tryon_msg(op: dict, generation: int) -> TryOnMsg:
    """The message of a Try-on button's op (couture.ui.tryon_panel)."""
    return TryOnMsg(
        op_id=uuid.uuid4().hex[:12],
        op=op["op"],
        panel=str(op.get("panel", "")),
        vector=Array.from_numpy(np.asarray(op.get("vector", [0.0, 0.0, 0.0])), "float64"),
        angle=float(op.get("angle", 0.0)),
        seam=int(op.get("seam", -1)),
        sewn=bool(op.get("sewn", True)),
        generation=generation,
    )


def adjust_msg(loop: str, amount: float, design: Design, design_id: str, generation: int) -> AdjustMsg:
    """The ``adjust`` request of the Adjust pattern folder."""
    return AdjustMsg(
        request_id=uuid.uuid4().hex[:12],
        edit=loop,  # type: ignore[arg-type]  # the folder offers only 'hem' and 'waist'; encode checks
        amount=float(amount),
        design=design,
        design_id=design_id,
        generation=generation,
    )


def edit_msg(edit: Edit, generation: int) -> EditMsg:
    """The ``edit`` message of one gesture phase, for the design of ``generation``."""
    pick = edit.pick
    return EditMsg(
        generation=generation,
        edit_id=edit.edit_id,
        phase=edit.phase,
        element=edit.element,
        dofs=list(edit.dofs),
        d=Array.from_numpy(np.asarray(edit.d, np.float64)),
        param=edit.param,
        picked_vertex=pick.vertex if pick else -1,
        picked_tri=pick.tri if pick else -1,
        picked_bary=Array.from_numpy(pick.bary) if pick else None,
        view_proj=Array.from_numpy(pick.view_proj) if pick and pick.view_proj is not None else None,
        viewport_px=list(pick.viewport_px) if pick and pick.viewport_px else [],
    )


def main(config: Config) -> None:
    ui = CoutureUI(UIConfig(host=config.host, port=config.port, export_dir=config.export_dir), design=config.design)
    # seen as live only once it listens: a client that waits for the ui and then
    # publishes a design must not race its subscriptions (a restarted ui missed it)
    with Node(config.name, config.bus, kind="ui", announce=False) as node:
        url = ui.start()
        try:
            adapter = UIAdapter(node, ui, config.name, bus_config=config.bus, record_dir=config.record_dir)
            node.announce()
            log.info("couture UI at %s (3D %s, pattern %s)", url, ui.url3d, ui.url2d)
            print(f"couture UI: {url}", flush=True)
            # a session already under way (the pattern topic keeps its last
            # sample for late joiners) wins over the default design
            node.stop_flag.wait(1.0)
            if config.publish_initial and not adapter.seen_pattern:
                adapter.publish_design(ui.design)
            try:
                node.run()
            finally:
                adapter.close()
        finally:
            ui.stop()
