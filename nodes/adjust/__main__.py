"""``python -m nodes.adjust --help``: the flags are the fields of :class:`nodes.adjust.main.Config` plus the bus flags."""

from couture.bus.nodeargs import run_node
from nodes.adjust.main import Config, main

if __name__ == "__main__":
    run_node(Config, main, "adjust")
