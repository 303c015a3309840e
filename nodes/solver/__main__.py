"""``python -m nodes.solver --help``: the flags are the fields of :class:`nodes.solver.main.Config` plus the bus flags."""

from couture.bus.nodeargs import run_node
from nodes.solver.main import Config, main

if __name__ == "__main__":
    run_node(Config, main, "solver")
