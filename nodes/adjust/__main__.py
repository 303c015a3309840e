import argparse
import logging

from couture.bus import add_bus_args, bus_config_from_args
from nodes.adjust.main import Config, main

if __name__ == "__main__":
    p = argparse.ArgumentParser(prog="python -m nodes.adjust")
    add_bus_args(p)
    p.add_argument("--name", default="adjust", help="node name, unique in the session")
    p.add_argument(
        "--vertices", type=int, default=Config.vertices, help="coarse mesh size of a request that names none"
    )
    p.add_argument(
        "--solver",
        action="append",
        default=[],
        metavar="NODE",
        help="solver node to send the solves to (repeatable; default: every live solver-* node)",
    )
    p.add_argument("--max-seconds", type=float, default=Config.max_seconds, help="[s] cap on each solve")
    a = p.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(asctime)s adjust %(levelname)s %(message)s")
    main(
        Config(
            bus=bus_config_from_args(a),
            name=a.name,
            vertices=a.vertices,
            solvers=a.solver,
            max_seconds=a.max_seconds,
        )
    )
