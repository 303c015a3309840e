import argparse
import logging
from pathlib import Path

from couture.bus import add_bus_args, bus_config_from_args
from nodes.ui.main import Config, main

if __name__ == "__main__":
    p = argparse.ArgumentParser(prog="python -m nodes.ui")
    add_bus_args(p)
    p.add_argument("--name", default="ui", help="node name, unique in the session")
    p.add_argument("--host", default="127.0.0.1", help="web UI host (default loopback)")
    p.add_argument(
        "--port",
        type=int,
        default=8080,
        help="the page designers open; the 3D view is port + 1, the pattern view port + 2; "
        "a taken port moves the page to the next free one (port + 3, ...), and the URL printed says where",
    )
    p.add_argument("--export-dir", type=Path, default=Path("out/exports"), help="where exports are written")
    p.add_argument(
        "--record-dir",
        type=Path,
        default=Path("out/recordings"),
        help="where the record toggle writes session-<time>.mcap when no recorder node runs",
    )
    p.add_argument(
        "--design",
        type=Path,
        default=None,
        help="pattern JSON to start from when the session has none yet (default: the default skirt)",
    )
    a = p.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(asctime)s ui %(levelname)s %(message)s")
    design = None
    if a.design is not None:
        from couture.client import load_design

        design = load_design(a.design)
    main(
        Config(
            bus=bus_config_from_args(a),
            name=a.name,
            host=a.host,
            port=a.port,
            export_dir=a.export_dir,
            record_dir=a.record_dir,
            design=design,
        )
    )
