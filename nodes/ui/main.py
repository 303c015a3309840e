"""The ui node: a thin adapter between the bus and :class:`couture.ui.CoutureUI`.

Messages in → ``CoutureUI.show_*``/``set_*`` (which only store the newest value
and return: Zenoh callback threads never wait on drawing); user actions →
messages out (``pattern`` on every design change, ``edit`` on every drag phase).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

from couture.bus import BusConfig, Node
from couture.ui import CoutureUI, UIConfig
from schemas.convert import msg_to_mesh
from schemas.design import Design
from schemas.messages import DrapeMsg, EditMsg, MeshMsg, PatternMsg, StatusMsg

log = logging.getLogger("couture.ui.node")


@dataclass
class Config:
    bus: BusConfig = field(default_factory=BusConfig)
    name: str = "ui"
    """node name, unique in the session (liveliness key status/<name>)"""
    host: str = "127.0.0.1"
    """viser binds here (loopback by default)"""
    port: int = 8080
    """3D view port; the pattern view is port + 1 and the combined page port + 2"""
    export_dir: Path = Path("out/exports")
    design: Design | None = None
    """initial design (None: the default skirt); published once at start"""
    publish_initial: bool = True


class UIAdapter:
    """Wires one CoutureUI to one bus. Separate from :func:`main` so tests can
    drive it with their own Node."""

    def __init__(self, node: Node, ui: CoutureUI, name: str):
        self.node, self.ui, self.name = node, ui, name
        bus = node.bus
        self.pattern_pub = bus.publisher("pattern", PatternMsg)
        self.edit_pub = bus.publisher("edit", EditMsg)
        self._own_edits: set[str] = set()
        self._drape_gen: dict[str, int] = {}
        self.seen_pattern = False
        ui.on_design_changed = self.publish_design
        ui.on_edit = self.publish_edit
        ui.on_solver_selected = lambda name: log.info("solver selected: %s", name)
        ui.on_record = lambda on: log.info("record %s (the recorder node records every session)", on)
        bus.subscribe("pattern", self.on_pattern)
        bus.subscribe("edit", self.on_edit)
        bus.subscribe("mesh/*", self.on_mesh)
        bus.subscribe("drape/*", self.on_drape)
        bus.subscribe("status/*", self.on_status)
        bus.watch_nodes(lambda n, alive: ui.set_live_nodes({n: alive}))

    # -- out
    def publish_design(self, design: Design) -> None:
        self.pattern_pub.put(PatternMsg(design=design, source=self.name, generation=self.ui.generation))
        self.node.count("pattern_out")

    def publish_edit(self, edit: dict) -> None:
        self._own_edits.add(edit["edit_id"])
        if len(self._own_edits) > 1000:
            self._own_edits.clear()
        self.edit_pub.put(EditMsg(generation=self.ui.generation, **edit))
        self.node.count("edit_out")

    # -- in (Zenoh threads: store and return)
    def on_pattern(self, msg: PatternMsg) -> None:
        self.seen_pattern = True
        if msg.source == self.name or msg.generation < self.ui.generation:
            return  # our own echo, or an older design (history can arrive out of order)
        self.ui.generation = msg.generation
        self.ui.set_design(msg.design)

    def on_edit(self, msg: EditMsg) -> None:
        if msg.edit_id in self._own_edits:
            return
        self.ui.apply_edit({"element": msg.element, "d": msg.d.numpy(), "phase": msg.phase})

    def on_mesh(self, msg: MeshMsg) -> None:
        self.ui.show_mesh(msg_to_mesh(msg))

    def on_drape(self, msg: DrapeMsg) -> None:
        # drop a drape older than one already shown at that level (reordering)
        if msg.generation < self._drape_gen.get(msg.level, -1):
            return
        self._drape_gen[msg.level] = msg.generation
        self.ui.show_drape(msg.x.numpy(), msg.level, msg.method or msg.solver,
                           residual=msg.residual, error_estimate=msg.error_estimate, generation=msg.generation)
        self.node.count("drape_in")

    def on_status(self, msg: StatusMsg) -> None:
        self.ui.set_node_status(msg.node, kind=msg.kind, state=msg.state, rates=msg.rates,
                                last_error=msg.last_error)


def main(config: Config) -> None:
    ui = CoutureUI(UIConfig(host=config.host, port=config.port, export_dir=config.export_dir),
                   design=config.design)
    with Node(config.name, config.bus, kind="ui") as node:
        url = ui.start()
        try:
            adapter = UIAdapter(node, ui, config.name)
            log.info("couture UI at %s (3D %s, pattern %s)", url, ui.url3d, ui.url2d)
            print(f"couture UI: {url}", flush=True)
            # a session already under way (the pattern topic keeps its last
            # sample for late joiners) wins over the default design
            node.stop_flag.wait(1.0)
            if config.publish_initial and not adapter.seen_pattern:
                adapter.publish_design(ui.design)
            node.run()
        finally:
            ui.stop()
