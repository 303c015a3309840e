import argparse
import logging

from couture.bus import add_bus_args, bus_config_from_args
from nodes.remesher.main import Config, main

if __name__ == "__main__":
    p = argparse.ArgumentParser(prog="python -m nodes.remesher")
    add_bus_args(p)
    p.add_argument("--name", default="remesher", help="node name, unique in the session")
    a = p.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(asctime)s remesher %(levelname)s %(message)s")
    main(Config(bus=bus_config_from_args(a), name=a.name))
