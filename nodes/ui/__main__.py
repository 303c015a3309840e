"""``python -m nodes.ui --help``: the flags are the fields of :class:`nodes.ui.main.Config` plus the bus flags."""

from couture.bus.nodeargs import run_node
from nodes.ui.main import Config, main

if __name__ == "__main__":
    run_node(Config, main, "ui")
