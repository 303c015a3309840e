"""``python -m nodes.remesher --help``: the flags are the fields of :class:`nodes.remesher.main.Config` plus the bus flags."""

from couture.bus.nodeargs import run_node
from nodes.remesher.main import Config, main

if __name__ == "__main__":
    run_node(Config, main, "remesher")
