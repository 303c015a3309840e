import argparse
import logging

from couture.bus import add_bus_args, bus_config_from_args
from nodes.solver.main import Config, main

if __name__ == "__main__":
    p = argparse.ArgumentParser(prog="python -m nodes.solver")
    add_bus_args(p)
    p.add_argument("--name", default="solver-kinetic", help="node name, unique in the session")
    p.add_argument("--solver", default="kinetic", choices=["kinetic", "newton", "verlet", "style3d"])
    p.add_argument(
        "--max-seconds", type=float, default=None, help="[s] cap on each level's solve (default: the service's)"
    )
    p.add_argument(
        "--backend",
        default=None,
        choices=["pardiso", "pardiso32", "cholmod", "splu"],
        help="direct linear-solver backend (default: $COUTURE_SOLVER_BACKEND, else the solver's own)",
    )
    p.add_argument(
        "--serve-session",
        action="append",
        default=[],
        metavar="NAME",
        help="serve this design session as a member of a solver pool (repeatable; every member gets the same "
        "list in the same order); --session is then the pool's own session, where members find each other",
    )
    a = p.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(asctime)s solver %(levelname)s %(message)s")
    main(
        Config(
            bus=bus_config_from_args(a),
            name=a.name,
            solver=a.solver,
            max_seconds=a.max_seconds,
            sessions=a.serve_session,
            **({"backend": a.backend} if a.backend else {}),
        )
    )
