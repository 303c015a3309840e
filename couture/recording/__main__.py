"""``python -m couture.recording --out FILE [KEYEXPR ...]``: the recorder node
(what ``couture up --record`` starts; ``couture record`` is the same). An
existing FILE is never written over: the recorder writes the next numbered
part (couture.recording.parts)."""

from __future__ import annotations

import argparse
import logging

from couture.bus import add_bus_args, bus_config_from_args
from couture.recording.recorder import RecordConfig, main


def build_parser(parser: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    p = parser or argparse.ArgumentParser(
        prog="python -m couture.recording", description="record couture messages to MCAP"
    )
    p.add_argument(
        "out",
        nargs="?",
        help="output .mcap file; when it exists, the next numbered part <stem>.<n>.mcap (never written over)",
    )
    p.add_argument("keyexprs", nargs="*", help="key expressions (default couture/<session>/**)")
    p.add_argument("--out", dest="out_flag", default=None, help="output .mcap file (alternative to the positional)")
    p.add_argument("--all-sessions", action="store_true", help="record couture/** instead of couture/<session>/**")
    p.add_argument("--flush-interval", type=float, default=0.5, help="close a chunk at least this often [s]")
    p.add_argument("--duration", type=float, default=0.0, help="stop after this long [s] (0: until Ctrl-C)")
    p.add_argument("--name", default="recorder", help="node name")
    p.add_argument(
        "--run-id",
        default="",
        help="continue this recording (its parts read back as one); default: a new one. "
        "`couture up` passes the same id to every restart of its recorder",
    )
    p.add_argument("--quiet", action="store_true", help="no throughput lines on stderr")
    add_bus_args(p)
    return p


def config_from_args(a: argparse.Namespace) -> RecordConfig:
    out = a.out_flag or a.out
    if not out:
        raise SystemExit("record: give an output file (OUT.mcap or --out OUT.mcap)")
    return RecordConfig(
        out=out,
        bus=bus_config_from_args(a),
        keyexprs=list(a.keyexprs),
        all_sessions=a.all_sessions,
        flush_interval_s=a.flush_interval,
        progress=not a.quiet,
        name=a.name,
        duration_s=a.duration,
        run_id=a.run_id,
    )


if __name__ == "__main__":
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(levelname)s %(message)s")
    main(config_from_args(build_parser().parse_args()))
