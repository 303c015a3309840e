"""Bus helpers: one Zenoh session per process, typed messages, presence.

from couture.bus import Node, BusConfig, add_bus_args, open_session
with open_session(BusConfig(session="s1", connect=["tcp/127.0.0.1:7447"])) as bus:
    pub = bus.publisher("drape/fine", DrapeMsg)
    bus.subscribe("mesh/*", lambda msg: ...)
"""

from couture.bus.node import PARENT_PID_ENV, Node, StopFlag
from couture.bus.ports import free_port
from couture.bus.session import (
    DEFAULT_ENDPOINT,
    DEFAULT_PORT,
    Bus,
    BusConfig,
    Stats,
    TypedPublisher,
    add_bus_args,
    bus_config_from_args,
    open_session,
)

__all__ = [
    "Bus",
    "BusConfig",
    "Node",
    "StopFlag",
    "Stats",
    "TypedPublisher",
    "DEFAULT_ENDPOINT",
    "DEFAULT_PORT",
    "PARENT_PID_ENV",
    "add_bus_args",
    "bus_config_from_args",
    "open_session",
    "free_port",
]
