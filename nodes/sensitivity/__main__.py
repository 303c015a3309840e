"""``python -m nodes.sensitivity --help``: the flags are the fields of :class:`nodes.sensitivity.main.Config` plus the bus flags."""

from couture.bus.nodeargs import run_node
from nodes.sensitivity.main import Config, main

if __name__ == "__main__":
    run_node(Config, main, "sensitivity")
