"""The solver node (placeholder): joins the bus with liveliness and status and idles.

The node logic replaces the body of :func:`main`; keep its signature.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from couture.bus import BusConfig, Node


@dataclass
class Config:
    bus: BusConfig = field(default_factory=BusConfig)
    name: str = "solver-kinetic"
    """node name, unique in the session (liveliness key status/<name>)"""
    solver: str = "kinetic"
    """which solver this node runs: kinetic, newton, verlet"""


def main(config: Config) -> None:
    with Node(config.name, config.bus, kind="solver") as node:
        node.run()
