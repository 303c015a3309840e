"""``couture`` command line: up, record, replay, compare, recover, export-foxglove, drape, export, bench."""

from __future__ import annotations

import argparse
import enum
import importlib
import json
import logging
import math
import shutil
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from couture.solvers import SOLVERS

if TYPE_CHECKING:
    from couture.graph import Graph
    from couture.supervisor import SupervisorConfig

DEFAULT_UI_PORT = 8080
"""where ``couture up`` serves its UI page when that port is free"""

BENCH_DIR = Path(__file__).resolve().parents[1] / "bench"
"""the benchmarks (package ``bench``, one module each): in the repository checkout
that couture runs from, never installed with it nor imported by it"""


def benches() -> list[str]:
    """Every benchmark's name (a module of bench/ with a main(argv)); none outside a checkout."""
    return sorted(p.stem for p in BENCH_DIR.glob("*.py") if not p.name.startswith("_"))


def run_bench(name: str, argv: list[str]) -> int:
    """``couture bench NAME ARGS``: ``bench.NAME.main(ARGS)``, the package found
    beside couture/ (the checkout's root goes on sys.path, as ``python -m
    bench.NAME`` run there would have it)."""
    if not (BENCH_DIR / "__init__.py").is_file():
        raise RuntimeError(
            f"the benchmarks are not installed with couture: run `couture bench` from a repository "
            f"checkout with its editable install (no {BENCH_DIR})"
        )
    if name not in benches():
        raise RuntimeError(f"no benchmark {name!r} in {BENCH_DIR}; choose from {benches()}")
    root = str(BENCH_DIR.parent)
    if root not in sys.path:
        sys.path.insert(0, root)
    mod = importlib.import_module(f"bench.{name}")
    if Path(mod.__file__ or "").resolve().parent != BENCH_DIR:
        raise RuntimeError(f"bench.{name} was imported from {mod.__file__}, not from {BENCH_DIR}")
    if not hasattr(mod, "main"):
        raise RuntimeError(f"benchmark {name!r} is not available yet (bench/{name}.py has no main)")
    return int(mod.main(argv) or 0)


def _parser() -> argparse.ArgumentParser:
    from couture.bus import add_bus_args
    from couture.recording.__main__ import build_parser as record_parser
    from schemas.topics import compared_topics, replayed_topics

    p = argparse.ArgumentParser(prog="couture", description="interactive garment design (Sensitive Couture) on Zenoh")
    p.add_argument("-v", "--verbose", action="store_true")
    sub = p.add_subparsers(dest="cmd", required=True)

    up = sub.add_parser(
        "up",
        help="start the nodes of a node graph (own processes, restarted on crash)",
        description="Start the nodes a node graph places on this machine, each its own process,\n"
        "restarted when it dies. Without --graph: couture/graphs/default.toml, the demo on one\n"
        "machine. Each node's flags come from its configuration in the graph (see\n"
        "`python -m nodes.<kind> --help` for a kind's keys).",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    up.add_argument(
        "--graph",
        metavar="FILE",
        default=None,
        help="node graph (TOML, couture/graph.py): nodes, the topics each takes and gives, their configuration "
        "and machines (default: couture/graphs/default.toml)",
    )
    up.add_argument(
        "--machine",
        metavar="NAME",
        default=None,
        help="run this machine's share of a graph over several machines; its router listens or connects as the "
        "graph's [machines.NAME] says unless --listen/--connect are given",
    )
    up.add_argument(
        "--set",
        dest="settings",
        action="append",
        default=[],
        metavar="NODE.KEY=VALUE",
        help="set one config value of a node (by name, or every node of a kind), e.g. solver.max_seconds=30 or "
        "ui.design=my.json; KEY is a field of the kind's Config, a list takes comma-separated items (repeatable)",
    )
    up.add_argument(
        "--record",
        metavar="FILE",
        help="also record the session to this MCAP file (never written over: when it exists, or when the "
        "recorder restarts, the next numbered part FILE-stem.<n>.mcap; replay FILE reads them all)",
    )
    up.add_argument("--no-ui", action="store_true", help="do not start the web UI node")
    up.add_argument(
        "--no-adjust", action="store_true", help="do not start the adjust node (the UI's Adjust pattern tool)"
    )
    up.add_argument(
        "--solver",
        nargs="+",
        default=None,
        metavar="NAME",
        help="solver nodes to run in place of the graph's (a name of couture.solvers.SOLVERS each; several for "
        "side-by-side comparison; the default graph runs newton: the accuracy reference, and the fastest to a "
        "converged fine drape after an edit, bench/results/edit_pattern.json)",
    )
    up.add_argument(
        "--only",
        nargs="+",
        metavar="NODE",
        default=None,
        help="start only these nodes of the graph (kinds: remesher, solver, sensitivity, adjust, ui, recorder; or "
        "node names), e.g. --only solver --connect tcp/<other machine>:7447; a graph with [machines] and --machine "
        "says the same in one file",
    )
    up.add_argument("--ui-host", default=None, help="host the UI binds (default: the graph's, 127.0.0.1)")
    up.add_argument(
        "--ui-port",
        type=int,
        default=None,
        help=f"port of the UI page (the views take the next two); default {DEFAULT_UI_PORT}, or the first free "
        "ports above it when another session holds it. A port given here that is taken is an error.",
    )
    add_bus_args(up)

    record_parser(sub.add_parser("record", help="record couture/** messages to MCAP"))

    inputs, outputs = " ".join(replayed_topics()), " ".join(compared_topics())
    rp = sub.add_parser("replay", help=f"publish recorded inputs ({inputs}) onto the bus")
    rp.add_argument(
        "path", nargs="+", help="recording(s): each file is read with its numbered parts (session.1.mcap, ...)"
    )
    rp.add_argument("--exact", action="store_true", help="read exactly the files given, not their numbered parts")
    rp.add_argument("--topics", nargs="+", default=None, help=f"relative topics to replay (default: {inputs})")
    rp.add_argument(
        "--rate", type=float, default=1.0, help="1: original timing, R: R times faster, 0: as fast as possible"
    )
    rp.add_argument("--loop", action="store_true")
    rp.add_argument("--wait-nodes", nargs="*", default=[], help="node names that must be live before sending")
    rp.add_argument("--wait-timeout", type=float, default=10.0, help="[s]")
    rp.add_argument(
        "--lockstep",
        action="store_true",
        help="after each pattern, wait for its final drape/fine (or a node's rejection of it) before sending on "
        "(deterministic regression runs)",
    )
    rp.add_argument("--lockstep-timeout", type=float, default=300.0, help="[s] per pattern in --lockstep mode")
    add_bus_args(rp)

    cp = sub.add_parser("compare", help="compare outputs of two recordings within tolerances")
    cp.add_argument("golden", help="golden recording (read with its numbered parts)")
    cp.add_argument("actual", help="actual recording (read with its numbered parts)")
    cp.add_argument("--json", metavar="OUT", help="write the report as JSON")
    cp.add_argument("--rtol", type=float, default=1e-5)
    cp.add_argument("--atol", type=float, default=1e-8, help="absolute tolerance [m for positions]")
    cp.add_argument("--topics", nargs="+", default=None, help=f"output topics (default: {outputs})")

    rc = sub.add_parser(
        "recover",
        help="rewrite a recording cut short (SIGKILL), with its numbered parts, into one finalized MCAP",
    )
    rc.add_argument("src", nargs="+", help="recording(s): each read with its numbered parts, up to the last flush")
    rc.add_argument("dst", help="new file (must not exist)")
    rc.add_argument("--exact", action="store_true", help="read exactly the files given, not their numbered parts")

    fx = sub.add_parser(
        "export-foxglove", help="copy a recording and add Foxglove-viewable channels (drape, body, pattern, log)"
    )
    fx.add_argument("src", help="recording (.mcap)")
    fx.add_argument("dst", help="output .mcap: every original message plus /foxglove/* protobuf channels")
    fx.add_argument(
        "--strain-max", type=float, default=0.10, help="top of the fixed strain colour range (Green strain)"
    )
    fx.add_argument("--no-body", action="store_true", help="leave out the mannequin")

    dp = sub.add_parser(
        "drape",
        help="drape a pattern file: start (or join) the nodes, write OBJ + pattern",
        description="Drape a pattern file once: start the nodes (or join a running session with\n"
        "--connect), publish the design, show each level's residual falling, and write\n"
        "drape.obj, drape.json and the pattern (JSON, DXF, SVG, PDF) into --out.",
        epilog=DRAPE_EXIT_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    dp.add_argument("pattern", help="pattern JSON (couture/design/v1)")
    dp.add_argument("--out", required=True, help="output directory")
    dp.add_argument(
        "--timeout",
        type=float,
        default=240.0,
        help="[s] to wait for the final fine drape (default 240: longer than the solver's own caps, "
        "so a slow solve ends with its diagnosis, exit 3, rather than a timeout, exit 5)",
    )
    dp.add_argument("--solver", default="newton", choices=sorted(SOLVERS))
    dp.add_argument(
        "--solver-max-seconds",
        type=float,
        default=None,
        metavar="S",
        help="[s] cap on each level's solve in the solver node this command starts "
        "(default: the solver's own; ignored with --connect)",
    )
    dp.add_argument(
        "--fabric",
        default=None,
        metavar="NAME",
        help="drape in this library fabric instead of the design's own (`couture fabrics` lists them)",
    )
    dp.add_argument(
        "--panel-fabric",
        action="append",
        default=[],
        metavar="PANEL=NAME",
        help="cut this panel from a library fabric (repeatable), e.g. waistband=denim",
    )
    dp.add_argument(
        "-v",
        "--verbose",
        dest="drape_verbose",
        action="store_true",
        help="also show node lifecycle and library logs (default: progress and the result only)",
    )
    dp.add_argument(
        "--name",
        default=None,
        help="this client's node name (with --tls: its certificate DIR/NAME.pem, which must be a writer)",
    )
    add_bus_args(dp)

    ex = sub.add_parser(
        "export",
        help="pattern pieces to cut: DXF (AAMA/ASTM), SVG, PDF, PDF tiled on A4/letter pages",
        description="Draft a pattern file and write its pieces to cut: the cut line (sew line plus seam\n"
        "allowance, deeper on hems), the sew line, notches where seams meet, drill holes at dart\n"
        "points, the grain line and labels (piece, size, how many to cut), at true scale.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ex.add_argument("pattern", help="pattern JSON (couture/design/v1)")
    ex.add_argument(
        "--format",
        nargs="+",
        default=["dxf", "svg", "pdf", "pdf-tiled"],
        choices=["dxf", "svg", "pdf", "pdf-tiled"],
        help="what to write (default: all): NAME.dxf, NAME.svg, NAME.pdf (one page), NAME-PAPER.pdf (tiled)",
    )
    ex.add_argument("--out", default=".", metavar="DIR", help="output directory (made if missing; default .)")
    ex.add_argument("--paper", default="a4", choices=["a4", "letter"], help="pages of pdf-tiled (default a4)")
    ex.add_argument("--seam-allowance", type=float, default=0.01, metavar="M", help="[m] default 0.01")
    ex.add_argument("--hem-allowance", type=float, default=0.03, metavar="M", help="[m] on hems, default 0.03")
    ex.add_argument(
        "--allowance",
        action="append",
        default=[],
        metavar="SEGMENT=M",
        help="[m] width on one seam, repeatable: 'neck=0.006' (that segment on every panel) or "
        "'front:side_right=0.015'; the seam's other side gets it too",
    )
    ex.add_argument("--hem-segments", nargs="+", default=["hem", "cuff"], metavar="NAME", help="segments that are hems")
    ex.add_argument(
        "--notch-spacing", type=float, default=0.25, metavar="M", help="[m] most seam between notches (0.25)"
    )
    ex.add_argument("--no-end-notches", action="store_true", help="no notches at seam ends")
    ex.add_argument(
        "--every-panel",
        action="store_true",
        help="one piece per panel (default: congruent panels, mirrored or not, are one piece with its cut count)",
    )
    ex.add_argument("--units", default="mm", choices=["mm", "in"], help="DXF units (default mm)")
    ex.add_argument("--sheet-width", type=float, default=1.2, metavar="M", help="[m] rows of pieces on the sheet (1.2)")
    ex.add_argument("--name", default=None, help="design name on the labels and files (default: the file's stem)")
    ex.add_argument("--size", default=None, help="size on the labels (default: the sloper's girths, e.g. B88 W70)")
    im = sub.add_parser(
        "import",
        help="pieces from other pattern tools (AAMA/ASTM DXF, FreeSewing SVG) -> a design to drape",
        description="Read the pattern pieces of a DXF (AAMA/ASTM: Gerber, Lectra, Optitex, CLO,\n"
        "Seamly2D/Valentina, couture export) or a FreeSewing SVG, unfold pieces cut on the fold,\n"
        "double 'cut 2' pieces into a left and a right, suggest seams (printed with a confidence;\n"
        "an unpaired edge is a free edge), place the pieces round the body and write a design\n"
        "that `couture drape` drapes. Nothing is written when the file cannot be imported.",
        epilog="exit status:\n  0  design written\n  2  bad command line\n"
        "  4  the file cannot be imported (file, piece and problem printed); nothing written",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    im.add_argument("file", help="DXF or SVG pattern file (told apart by content)")
    im.add_argument("--out", required=True, help="design JSON to write (couture/design/v1)")
    im.add_argument(
        "--units",
        default=None,
        choices=["mm", "cm", "in", "m"],
        help="file units where the file does not say (DXF without $INSUNITS: default detected from the piece sizes)",
    )
    im.add_argument(
        "--body",
        default=None,
        metavar="MEASUREMENTS.json",
        help="the measurement set the pattern was drafted for (FreeSewing names, mm: chest, waist, seat/hips, "
        "height, inseam): the design takes the nearest shipped body, or, when that is more than 1 cm rms off, "
        "a body of the set's own measurements named after the file (the nearest warped to them: "
        "couture.bodies.warp; docs/bodies.md)",
    )
    im.add_argument(
        "--seam-allowance",
        type=float,
        default=0.0,
        metavar="M",
        help="[m] a DXF piece with a cut line and no sew line (layer 14) is sewn this far inside it (default 0)",
    )
    im.add_argument(
        "--landmark",
        default=None,
        choices=["waist", "shoulder"],
        help="where the pieces' tops go (default: shoulder for a top with sleeves/collar, else waist)",
    )
    im.add_argument(
        "--exclude",
        nargs="+",
        action="extend",
        default=[],
        metavar="PIECE",
        help="pieces to leave out (e.g. waistband)",
    )
    im.add_argument(
        "--stretch-stiffness",
        type=float,
        default=200.0,
        metavar="N_PER_M",
        help="[N/m] the fabric's in-plane stiffness (default 200: a woven; couture's default cotton is 20)",
    )
    im.add_argument(
        "--fabric",
        default=None,
        metavar="NAME",
        help="the design's fabric from the library (`couture fabrics`); overrides --stretch-stiffness",
    )
    im.add_argument(
        "--min-confidence",
        type=float,
        default=0.5,
        metavar="C",
        help="suggested seams below this confidence are listed but not sewn (default 0.5)",
    )

    fb = sub.add_parser(
        "fabrics",
        help="the fabric library: name, density, stiffness, bending, Peirce bending length, sources",
        description="List the library fabrics (couture/assets/fabrics/library.toml) that --fabric and the UI\n"
        "offer, with their key numbers; --source NAME prints where every number of one fabric comes from.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    fb.add_argument("--source", default=None, metavar="NAME", help="every number of one fabric with its source")
    fb.add_argument("--json", action="store_true", help="print the library as JSON")

    ad = sub.add_parser(
        "adjust",
        help="direct 3D edit of a draped design (hem, waist) and its physics-adjusted pattern (Bartle 2016)",
        description="Drape a design on solver nodes, edit the drape in 3D (hem shorter or longer, waist\n"
        "looser or tighter) into a target garment, and adjust the pattern until its re-simulated drape matches\n"
        "the target. Every solve is a `solve` request over the bus: without --connect the solver nodes\n"
        "(--solver, repeatable; two names fan the solves out over two processes) are started here.\n"
        "Writes pattern.dxf/.svg/.pdf (adjusted), flattened.svg, panels.json, drape_*.obj, adjust.json\n"
        "and adjust.png into --out, and design.json: the design the UI's adjust tool publishes for the same\n"
        "edit (the sloper's options fitted to the adjusted pattern, corrected on its own drapes; --no-fit: not).\n"
        "The settings are couture.adjust.settings.DEFAULTS, the adjust node's.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ad.add_argument("pattern", help="pattern JSON (couture/design/v1)")
    edit = ad.add_mutually_exclusive_group(required=True)
    edit.add_argument(
        "--hem", type=float, metavar="DH", help="[m] hem change; negative shortens (e.g. -0.15), positive lengthens"
    )
    edit.add_argument("--waist", type=float, metavar="DG", help="[m] waist girth change; positive loosens (e.g. +0.04)")
    ad.add_argument("--out", required=True, help="output directory")
    ad.add_argument(
        "--solver",
        action="append",
        default=None,
        choices=sorted(SOLVERS),
        help="solver node(s) to start and fan the solves out to (repeatable; default newton); with --connect: "
        "which live solver-<name> nodes to use (default every live one)",
    )
    ad.add_argument(
        "--vertices",
        type=int,
        default=None,
        help="coarse mesh size (default the design's resolution.coarse_vertices; the UI's adjust node: 400)",
    )
    from couture.adjust.settings import DEFAULTS as ADJ
    from couture.adjust.settings import GOAL as ADJ_GOAL

    ad.add_argument(
        "--iters",
        type=int,
        default=None,
        help=f"at most this many fixed-point updates (default {ADJ.updates})",
    )
    ad.add_argument(
        "--start",
        choices=["source", "flatten"],
        default=None,
        help="iteration 0's pattern: 'source', one fixed-point update from the source pattern and its drape; "
        f"'flatten', the target flattened per panel (Bartle's start); default {ADJ.start}",
    )
    ad.add_argument(
        "--stop-stretch",
        type=float,
        default=None,
        help=f"stop the updates once the mean stretch (eq. 8) reaches this (default {ADJ.stop_stretch})",
    )
    ad.add_argument("--no-equalize", action="store_true", help="leave the seam lengths as the embedding makes them")
    ad.add_argument(
        "--no-fit",
        action="store_true",
        help="do not fit the design's options to the adjusted pattern (no design.json, no drapes of the fit)",
    )
    ad.add_argument(
        "--gradient-steps",
        type=int,
        default=None,
        metavar="N",
        help="after the fixed point, up to N Gauss-Newton steps on the distance to the target and the drape's "
        "stretch, with couture's design sensitivity (each re-simulated on the solver nodes, kept only if it lowers "
        f"the Hausdorff distance and keeps the mean stretch >= 0.98); default {ADJ.gradient_steps}",
    )
    ad.add_argument(
        "--stretch-weight",
        type=float,
        default=None,
        metavar="W",
        help=f"the gradient steps' stretch weight (default {ADJ.stretch_weight:g})",
    )
    ad.add_argument(
        "--max-solves",
        type=int,
        default=None,
        metavar="N",
        help=f"re-simulated patterns in all, the start pattern's included (default {ADJ.max_solves})",
    )
    ad.epilog = (
        f"The defaults were chosen once for every example design and edit (couture bench adjust_sweep).\n"
        f"Goal: Hausdorff <= {ADJ_GOAL.hausdorff_pct:g} % of height, mean stretch >= {ADJ_GOAL.stretch:g}, "
        f"<= {ADJ_GOAL.solves} re-simulated patterns, <= {ADJ_GOAL.seconds:g} s.\n"
        "exit status:\n  0  goal met; every output written\n  1  error (a refused edit says why)\n"
        "  2  bad command line\n  3  goal not met: every output written, the reasons measured and printed\n"
        "(a design no sloper option can express writes no design.json and says why; the status is the goal's)"
    )
    add_bus_args(ad)

    from couture.bus.secure import DEFAULT_HOSTS, DEFAULT_WRITERS, STANDARD_NODES

    ct = sub.add_parser(
        "certs",
        help="make a development CA, node certificates and an access policy for a secured session (--tls DIR)",
        description="Make (or add to) a secure directory for `couture up --tls DIR` and `--tls DIR` on nodes\n"
        "and clients: a development CA (kept when DIR has one), one key (mode 0600) and certificate per\n"
        "node (common name = the node's --name; 'router' is the supervisor's) and policy.json, the\n"
        "names that may change the design (put on pattern and edit) and answer solve queries.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ct.add_argument("--out", required=True, metavar="DIR", help="the secure directory (made if missing)")
    ct.add_argument(
        "--nodes",
        nargs="+",
        default=list(STANDARD_NODES),
        metavar="NAME",
        help="node names to issue certificates for (default: every node `couture up` may start: %(default)s)",
    )
    ct.add_argument(
        "--writers",
        nargs="*",
        default=None,
        metavar="NAME",
        help=f"names that may publish pattern and edit, added to the policy (default: those of {list(DEFAULT_WRITERS)} "
        "among --nodes); they get certificates too",
    )
    ct.add_argument(
        "--solvers",
        nargs="*",
        default=None,
        metavar="NAME",
        help="names that may answer solve queries, added to the policy (default: the solver-* among --nodes)",
    )
    ct.add_argument(
        "--host",
        action="append",
        dest="hosts",
        default=None,
        metavar="HOST",
        help=f"IP address or DNS name the certificates are valid for (repeatable; default {' and '.join(DEFAULT_HOSTS)})",
    )
    ct.add_argument("--days", type=int, default=365, help="validity of the node certificates [days]")

    gp = sub.add_parser("golden", help="golden recordings: make or check recordings/<case>.mcap", add_help=False)
    gp.add_argument("rest", nargs=argparse.REMAINDER)

    bo = sub.add_parser(
        "bodies", help="bodies a design can name: list them (requested vs measured), or make the graded sizes"
    )
    bsub = bo.add_subparsers(dest="bodies_cmd", required=True)
    bl = bsub.add_parser("list", help="print every body with its requested and measured ISO 8559-1 measurements")
    bl.add_argument("--json", action="store_true", help="print the table as JSON")
    bm = bsub.add_parser(
        "make", help="fit the graded sizes with Anny and write couture/assets/bodies (needs couture[bodies])"
    )
    bm.add_argument("names", nargs="*", help="sizes to make (default: every size of the table)")
    bm.add_argument("--out", default=None, help="directory (default: couture/assets/bodies)")
    bm.add_argument(
        "--measure",
        nargs=5,
        type=float,
        metavar=("HEIGHT", "BUST", "WAIST", "HIP", "INSEAM"),
        default=None,
        help="a body of your own measurements [m] (stature, bust, waist and hip girths, inside leg), "
        "named by the one NAME given",
    )
    bm.add_argument(
        "--method",
        choices=("auto", "anny", "warp"),
        default="auto",
        help="anny: fit the Anny body model (couture[bodies]); warp: deform the nearest shipped body to "
        "--measure (couture.bodies.warp, no extra); auto (default): anny when installed, else warp",
    )

    bp = sub.add_parser(
        "bench", help="benchmarks: NAME writes NAME.json (and its plots) to --out DIR (default bench/results/)"
    )
    bp.add_argument("which", choices=benches() or None, help="the benchmark (a module of bench/)")
    bp.add_argument("args", nargs=argparse.REMAINDER, help="passed to the benchmark, e.g. --out DIR")
    return p


def parse_panel_fabrics(items: list[str]) -> dict[str, str]:
    """['waistband=denim', ...] -> {'waistband': 'denim'}; a ValueError naming a malformed item."""
    out: dict[str, str] = {}
    for item in items:
        panel, sep, fabric = item.partition("=")
        if not sep or not panel or not fabric:
            raise ValueError(f"--panel-fabric {item!r}: use PANEL=NAME, e.g. waistband=denim")
        out[panel] = fabric
    return out


def with_library_fabrics(design, fabric: str | None, panel_fabrics: dict[str, str]):
    """The design with its fabric (and panels' own fabrics) taken from the
    library by name; unknown fabric or panel names raise ValueError."""
    import msgspec

    from couture import fabrics

    if fabric is not None:
        design = msgspec.structs.replace(design, fabric=fabrics.get(fabric))
    if panel_fabrics:
        from couture.pattern.draft import draft

        panels = [p.name for p in draft(design).panels]
        bad = sorted(set(panel_fabrics) - set(panels))
        if bad:
            raise ValueError(f"--panel-fabric: no panel {bad[0]!r} in the design; its panels are {panels}")
        own = dict(design.panel_fabrics)
        own.update({p: fabrics.get(n) for p, n in panel_fabrics.items()})
        design = msgspec.structs.replace(design, panel_fabrics=own)
    return design


def fabrics_command(args: argparse.Namespace) -> int:
    """``couture fabrics``: the library as a table (or one fabric's sources, or JSON)."""
    from couture import fabrics

    if args.source is not None:
        e = fabrics.entry(args.source)
        print(f"{e.name}: {e.label} ({e.kind}; linear fit valid to {100 * e.valid_strain:g} % strain)")
        for field in (*fabrics.NUMBERS, "valid_strain"):
            v = e.valid_strain if field == "valid_strain" else getattr(e.fabric, field)
            print(f"  {field:18s} {v:<10.4g} {e.sources[field]}")
        for key, ref in fabrics.references().items():
            print(f"  [{key}] {ref}")
        return 0
    entries = [fabrics.entry(n) for n in fabrics.names()]
    if args.json:
        import msgspec

        from couture.jsonout import dumps

        print(
            dumps(
                [
                    {
                        "name": e.name,
                        "label": e.label,
                        "kind": e.kind,
                        "valid_strain": e.valid_strain,
                        "fabric": msgspec.to_builtins(e.fabric),
                        "sources": e.sources,
                    }
                    for e in entries
                ],
                indent=2,
            )
        )
        return 0
    print(
        f"{'name':16s} {'kind':5s} {'g/m2':>5s} {'mm':>5s} {'warp':>6s} {'weft':>6s} {'shear':>6s} N/m  "
        f"{'bend warp':>9s} {'weft':>8s} {'bias':>8s} N m  {'c cm':>5s} {'mu_s':>4s}  measured"
    )
    for e in entries:
        f = e.fabric
        measured = [k for k, v in e.sources.items() if v.startswith("measured")]
        print(
            f"{e.name:16s} {e.kind:5s} {1000 * f.area_density:5.0f} {1000 * (f.thickness or 0):5.2f} "
            f"{f.warp_stiffness:6.0f} {f.weft_stiffness:6.0f} {f.shear_stiffness:6.1f}      "
            f"{f.bend_warp:9.2e} {f.bend_weft:8.2e} {f.bend_bias:8.2e}      {100 * e.bending_length_warp:5.2f} "
            f"{f.friction_static:4.2f}  {', '.join(measured) or '-'}"
        )
    print("every number's source: couture fabrics --source NAME (the rest are estimates of the fabric class)")
    return 0


IMPORT_BAD_FILE = 4
"""exit status of ``couture import`` for a file that cannot be imported"""


def import_pattern(args: argparse.Namespace) -> int:
    """``couture import``: a DXF/SVG pattern's pieces -> a design file (see its --help)."""
    import msgspec

    from couture.pattern.errors import PatternError
    from couture.pattern.imported import read_pattern
    from couture.pattern.io import design_to_json
    from couture.pattern.sewing import body_of_measurements, build_design
    from couture.pattern.validate import validate
    from schemas.design import Body

    out = Path(args.out)
    try:
        body: str | Body = "default"
        body_note = ""
        if args.body:
            try:
                meas = json.loads(Path(args.body).read_text())
            except (OSError, ValueError) as e:
                raise PatternError(args.body, f"not a measurement set (JSON): {e}") from None
            body, body_note = body_of_measurements(meas, args.body, name=Path(args.body).stem)
        pieces = read_pattern(args.file, units=args.units, seam_allowance=args.seam_allowance)
        design, rep = build_design(
            pieces,
            body=body,
            landmark=args.landmark,
            exclude=tuple(args.exclude),
            min_confidence=args.min_confidence,
            stretch_stiffness=args.stretch_stiffness,
        )
        if args.fabric is not None:
            design = with_library_fabrics(design, args.fabric, {})
        try:
            validate(design)
        except PatternError as e:
            raise PatternError(f"{args.file}:{e.element}", str(e).split(": ", 1)[-1]) from None
        data = design_to_json(design)
    except PatternError as e:
        print(f"couture import: {e}", file=sys.stderr)
        return IMPORT_BAD_FILE
    print(f"{args.file}: {len(pieces)} pieces -> {len(rep.panels)} panels: {', '.join(rep.panels)}")
    if body_note:
        print(f"body: {body_note}")
    for note in rep.notes:
        print(f"note: {note}")
    rings: dict[str, list[str]] = {}
    for pc in sorted(design.pieces, key=lambda pc: pc.placement.position):
        rings.setdefault(pc.placement.ring, []).append(pc.name)
    where = "; ".join(f"{ring.replace('_', ' ')}: {' -> '.join(names)}" for ring, names in rings.items())
    print(f"placement (round each ring from the front): {where or '-'}; tops at the {rep.landmark}")
    print(f"seams suggested ({len(rep.seams)}, sewn at confidence >= {args.min_confidence:g}):")
    for sm in rep.seams:
        print(
            f"  {sm.a_panel}:{sm.a_segment} ({sm.a_length * 100:.1f} cm) + {sm.b_panel}:{sm.b_segment} "
            f"({sm.b_length * 100:.1f} cm)  confidence {sm.confidence:.2f}  {sm.reason}"
        )
    print(f"free edges ({len(rep.free)}): " + ", ".join(f"{p}:{g} {ln * 100:.1f} cm" for p, g, ln in rep.free))
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_bytes(data)
    tmp.replace(out)  # whole or not at all
    print(f"wrote {out} ({msgspec.json.decode(data)['schema']})")
    return 0


def bodies_command(args: argparse.Namespace) -> int:
    import couture.bodies as bodies
    from couture.bodies.measure import MEASURES

    if args.bodies_cmd == "make":
        from couture.bodies.make import anny_available, make_graded, make_warped
        from couture.pattern.sections import write_body_sections

        table = None
        if args.measure is not None:
            if len(args.names) != 1:
                raise ValueError("--measure makes one body: give exactly one NAME")
            table = {args.names[0]: dict(zip(MEASURES, args.measure, strict=True))}
        method = args.method if args.method != "auto" else ("anny" if anny_available() else "warp")
        if method == "warp":
            if table is None:
                raise ValueError("--method warp makes a body of --measure: give one NAME and --measure")
            if args.method == "auto":
                print("Anny is not installed: warping the nearest shipped body (couture.bodies.warp)", file=sys.stderr)
            name = args.names[0]
            make_warped(Path(args.out) if args.out else bodies.BODIES_DIR, name, table[name], write_body_sections)
            bodies.index.cache_clear()
            return bodies_command(argparse.Namespace(bodies_cmd="list", json=getattr(args, "json", False)))
        make_graded(
            Path(args.out) if args.out else bodies.BODIES_DIR,
            args.names or None,
            table=table,
            write_sections=write_body_sections,
        )
        bodies.index.cache_clear()
    rows = bodies.table()
    if getattr(args, "json", False):
        print(json.dumps(rows, indent=2))
        return 0
    print("requested / measured [cm] (ISO 8559-1: stature, bust, waist, hip girths, inside leg)")
    print(f"{'body':8s}" + "".join(f"{k:>22s}" for k in MEASURES))
    for r in rows:
        cells = []
        for k in MEASURES:
            m = 100 * r["measured"][k]
            req = (r["requested"] or {}).get(k)
            cells.append(f"{m:.1f}" if req is None else f"{100 * req:.1f} / {m:.1f}")
        print(f"{r['name']:8s}" + "".join(f"{c:>22s}" for c in cells))
    return 0


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO, format="%(asctime)s %(name)s %(levelname)s %(message)s"
    )
    try:
        return int(_dispatch(args) or 0)
    except (TimeoutError, ValueError, FileNotFoundError, FileExistsError, RuntimeError) as e:
        print(f"couture {args.cmd}: error: {e}", file=sys.stderr)
        return 1


def _dispatch(args: argparse.Namespace) -> int:
    from couture.bus import bus_config_from_args

    if args.cmd == "up":
        return up(args)

    if args.cmd == "certs":
        from couture.bus.secure import POLICY_FILE, Policy, make_certs

        written = make_certs(
            args.out, args.nodes, writers=args.writers, solvers=args.solvers, hosts=args.hosts, days=args.days
        )
        policy = Policy.load(Path(args.out) / POLICY_FILE)
        print(f"wrote {len(written)} files to {args.out} (keys mode 0600)")
        print(f"  may publish pattern/edit: {', '.join(policy.writers) or 'nobody'}")
        print(f"  may answer solve:         {', '.join(policy.solvers) or 'nobody'}")
        print(f"run: couture up --tls {args.out}")
        return 0

    if args.cmd == "record":
        from couture.recording.__main__ import config_from_args
        from couture.recording.recorder import main as record

        record(config_from_args(args))
        return 0

    if args.cmd == "golden":
        from couture.recording.golden import main as golden

        return golden(args.rest)

    if args.cmd == "replay":
        from couture.recording.replay import ReplayConfig
        from couture.recording.replay import main as replay

        cfg = ReplayConfig(
            path=args.path,
            parts=not args.exact,
            bus=bus_config_from_args(args),
            rate=args.rate,
            loop=args.loop,
            wait_nodes=args.wait_nodes,
            wait_timeout_s=args.wait_timeout,
            lockstep=args.lockstep,
            lockstep_timeout_s=args.lockstep_timeout,
        )
        if args.topics:
            cfg.topics = args.topics
        replay(cfg)
        return 0

    if args.cmd == "compare":
        from couture.recording.compare import compare, write_json

        rep = compare(args.golden, args.actual, rtol=args.rtol, atol=args.atol, topics=args.topics)
        print(rep.text())
        if args.json:
            write_json(rep, args.json)
        return 0 if rep.ok else 1

    if args.cmd == "recover":
        from couture.recording.mcapio import recover
        from couture.recording.parts import describe, resolve

        files = resolve(args.src, parts=not args.exact)
        n = recover(files, args.dst, parts=False)
        print(f"recovered {n} messages from {describe(files)} into {args.dst}")
        return 0

    if args.cmd == "export-foxglove":
        from couture.recording.foxglove import MANNEQUIN_OBJ, export_foxglove

        st = export_foxglove(
            args.src, args.dst, strain_max=args.strain_max, body=None if args.no_body else MANNEQUIN_OBJ
        )
        print(f"{args.dst}: {st.text()}")
        return 0

    if args.cmd == "drape":
        return drape(
            args.pattern,
            args.out,
            bus=bus_config_from_args(args),
            timeout=args.timeout,
            solver=args.solver,
            solver_max_seconds=args.solver_max_seconds,
            verbose=args.verbose or args.drape_verbose,
            name=args.name,
            fabric=args.fabric,
            panel_fabrics=parse_panel_fabrics(args.panel_fabric),
        )

    if args.cmd == "fabrics":
        return fabrics_command(args)

    if args.cmd == "export":
        return export_pattern(args)
    if args.cmd == "import":
        return import_pattern(args)
    if args.cmd == "adjust":
        return adjust(args)
    if args.cmd == "bodies":
        return bodies_command(args)

    if args.cmd == "bench":
        return run_bench(args.which, args.args)
    raise AssertionError(args.cmd)


def up(args: argparse.Namespace) -> int:
    """``couture up``: the graph's nodes on this machine, as adjusted by the flags."""
    from couture import supervisor

    try:
        config, graph = up_plan(args)
    except ValueError as e:
        print(f"couture up: {e}", file=sys.stderr)
        return 2
    print(
        f"[up] graph {graph.source}" + (f", machine {args.machine}" if args.machine else "") + ": "
        f"{', '.join(n.name for n in config.nodes) or 'no nodes'}",
        file=sys.stderr,
        flush=True,
    )
    return supervisor.main(config)


def up_plan(args: argparse.Namespace) -> tuple[SupervisorConfig, Graph]:
    """What ``couture up ARGS`` starts, without starting it: the supervisor's
    config (its bus, the node processes, the UI's URL) and the graph it came
    from. A bad graph or flag raises ValueError (GraphError) saying which."""
    from couture import supervisor
    from couture.bus import bus_config_from_args
    from couture.graph import load_graph

    graph = load_graph(args.graph)
    if args.solver:
        graph = graph.with_solvers(args.solver)
    for kind, off in (("adjust", args.no_adjust), ("ui", args.no_ui)):
        if off:
            graph = graph.without(kind)
    for item in args.settings:
        target, eq, value = item.partition("=")
        node, dot, key = target.rpartition(".")
        if not eq or not dot or not node or not key:
            raise ValueError(f"--set {item!r} is not NODE.KEY=VALUE (e.g. solver.max_seconds=30)")
        graph.set(node, key, value)
    extra = [supervisor.recorder_node(args.record)] if args.record else []
    here = {n.name for n in supervisor.only_nodes(supervisor.graph_nodes(graph, args.machine) + extra, args.only)}
    url = ""
    for n in graph.nodes:
        if n.kind == "ui" and n.name in here:
            host = args.ui_host or str(n.config.get("host", "127.0.0.1"))
            port = ui_port_for(host, args.ui_port, int(n.config.get("port", DEFAULT_UI_PORT)))
            graph.set(n.name, "host", host)
            graph.set(n.name, "port", str(port))
            url = url or f"http://{host}:{port}/"
    # the nodes' command lines, written from the graph once the ports are known
    nodes = [n for n in supervisor.graph_nodes(graph, args.machine) + extra if n.name in here]
    if args.tls and any(n.name == "adjust" for n in nodes) and not (Path(args.tls) / "adjust.pem").exists():
        # a secure directory made before the adjust node existed: run without it
        nodes = [n for n in nodes if n.name != "adjust"]
        print(
            f"couture up: no certificate for the adjust node in {args.tls}: started without it "
            f"(add it: couture certs --out {args.tls} --nodes adjust --writers adjust)",
            file=sys.stderr,
        )
    bus = bus_config_from_args(args)
    if args.machine is not None:  # the graph says how this machine's router links to the others
        machine = graph.machines[args.machine]
        if not args.listen and machine.listen:
            bus.listen = list(machine.listen)
        if not args.connect and machine.connect:
            bus.connect = list(machine.connect)
    return supervisor.SupervisorConfig(bus=bus, nodes=nodes, ui_url=url), graph


def ui_port_for(host: str, asked: int | None, default: int = DEFAULT_UI_PORT) -> int:
    """The UI page's port for ``couture up``: ``asked`` when it is free (a
    taken one raises RuntimeError naming it: the user chose it), else
    ``default`` (the graph's) when it and the views' two ports after it are free, else
    the first such block above it. The UI node binds it, or, should another
    process take it meanwhile, the next free one (it prints its own URL)."""
    from couture.bus.ports import free_port_block, port_is_free

    if asked is not None:
        if not port_is_free(asked, host):
            raise RuntimeError(
                f"--ui-port {asked}: port {asked} on {host} is already in use (another couture up?); "
                "choose another port, or leave --ui-port out to take a free one"
            )
        return asked
    port = free_port_block(default, 3, host)
    if port != default:
        print(
            f"[up] ports {default}-{default + 2} are not all free (another couture up?): "
            f"this session's UI is on port {port}",
            file=sys.stderr,
            flush=True,
        )
    return port


class DrapeExit(enum.IntEnum):
    """Exit status of ``couture drape``; meanings in ``_DRAPE_EXIT_TEXT`` (shown by --help)."""

    CONVERGED = 0
    ERROR = 1
    USAGE = 2
    NOT_CONVERGED = 3
    BAD_DESIGN = 4
    TIMEOUT = 5


_DRAPE_EXIT_TEXT = {
    DrapeExit.CONVERGED: "converged fine drape; every output written",
    DrapeExit.ERROR: "error: missing file, a node failed, no matching mesh",
    DrapeExit.USAGE: "bad command line",
    DrapeExit.NOT_CONVERGED: "the solver stopped short of its tolerance: drape written anyway, diagnosis printed",
    DrapeExit.BAD_DESIGN: "bad design: not a couture/design/v1 file (file, line and column of a JSON error "
    "printed), or a node rejected it (the field, its value and the allowed range printed, within about a "
    "second); no drape written",
    DrapeExit.TIMEOUT: "no final fine drape within --timeout; no drape written",
}
DRAPE_EXIT_HELP = "exit status:\n" + "\n".join(f"  {int(c)}  {t}" for c, t in _DRAPE_EXIT_TEXT.items())


class _DrapeProgress:
    """One bar per level: the relative residual on a log scale, from the
    level's first reported residual down to its tolerance, fed by the
    solver's progress drapes. Bars only on a terminal; each level's final
    result is printed as one line either way."""

    def __init__(self, tol: dict[str, float], stream=sys.stderr) -> None:
        from tqdm import tqdm

        self._tqdm = tqdm
        self.tol = tol
        """relative residual each level stops at (the solver service's defaults)"""
        self.stream = stream
        self.bars: dict[str, object] = {}
        self.r0: dict[str, float] = {}
        self.finals: dict[str, object] = {}

    def __call__(self, msg) -> None:
        level = msg.level
        if level in self.finals:
            return  # a late progress snapshot after the level's result
        r = float(msg.residual)
        for other in self.bars:  # a level is done once the next one reports
            if other != level:
                self._close(other)
        if level not in self.bars and not msg.final:
            self.r0[level] = r if math.isfinite(r) and r > 0 else 1.0
            # tqdm takes a pseudo-terminal that reports no size as -1 rows and
            # then draws nothing; shutil falls back to 80x24 there
            cols, rows = shutil.get_terminal_size()
            self.bars[level] = self._tqdm(
                total=100,
                desc=f"{level:>6}",
                leave=True,
                file=self.stream,
                disable=None,
                ncols=cols,
                nrows=rows,
                bar_format="{desc} {bar:30} {postfix}",
            )
        bar = self.bars.get(level)
        if bar is not None:
            if math.isfinite(r) and r > 0:
                span = math.log10(max(self.r0[level], self.tol[level] * 10) / self.tol[level])
                frac = math.log10(max(self.r0[level], r) / r) / span
                # the fill keeps the best so far (a residual may rise for a while); the text shows the latest
                bar.n = max(bar.n, int(round(100 * min(max(frac, 0.0), 1.0))))  # type: ignore[attr-defined]
            bar.set_postfix_str(  # type: ignore[attr-defined]
                f"residual {r:.2e} -> {self.tol[level]:.0e}, {msg.iterations} its",
                refresh=True,
            )
        if msg.final:
            self.finals[level] = msg
            self._close(level)
            print(f"[drape] {level}: {_describe(msg, self.tol[level])}", file=self.stream, flush=True)

    def _close(self, level: str) -> None:
        bar = self.bars.get(level)
        if bar is not None and not getattr(bar, "_closed_by_us", False):
            bar.refresh()  # type: ignore[attr-defined]
            bar.close()  # type: ignore[attr-defined]
            bar._closed_by_us = True  # type: ignore[attr-defined]

    def close(self) -> None:
        for level in self.bars:
            self._close(level)


def _describe(d, tol: float) -> str:
    """One line for a level's final drape: state, residual, iterations, time, solver, why."""
    state = "converged" if d.converged else "NOT converged"
    why = f": {d.diagnosis}" if d.diagnosis else ""
    built = f"; {d.x.numpy().shape[0]} vertices, terms {', '.join(d.terms)}" if d.terms else ""
    return (
        f"{state}, residual {d.residual:.2e} (tolerance {tol:.0e}) after {d.iterations} iterations in "
        f"{d.wall_time_s:.1f} s ({d.solver}, {d.method}{built}){why}"
    )


def drape(
    pattern: str,
    out: str,
    *,
    bus,
    timeout: float = 240.0,
    solver: str = "newton",
    solver_max_seconds: float | None = None,
    verbose: bool = False,
    name: str | None = None,
    fabric: str | None = None,
    panel_fabrics: dict[str, str] | None = None,
) -> int:
    """Drape a pattern file: join the bus given by ``bus.connect`` or start the
    nodes (no UI), publish the pattern, wait for the final drape/fine of that
    generation while showing each level's residual, and write ``drape.obj``
    (pattern as texture coordinates), ``drape.json`` (solver, residual,
    converged, diagnosis), ``pattern.json`` and the cuttable pattern as
    ``pattern.dxf`` (AAMA-style), ``pattern.svg`` and ``pattern.pdf`` (true
    scale) into ``out``. Returns a :class:`DrapeExit` code: 0 only for a
    converged fine drape.

    Node output (lifecycle, library logs) goes to ``out/nodes.log`` unless
    ``verbose``; ``timeout`` [s] bounds the wait for the fine drape and
    ``solver_max_seconds`` [s] caps each level's solve in a started solver;
    ``name`` is the client's node name (its certificate with ``bus.tls``);
    ``fabric`` a library fabric the design is draped in instead of its own,
    ``panel_fabrics`` panel name -> library fabric (``Design.panel_fabrics``)."""
    from contextlib import ExitStack

    from couture import supervisor
    from couture.client import Client, PatternRejected, load_design
    from couture.jsonout import dumps
    from couture.solvers.service import DEFAULT_TOL

    if bus.tls:
        from couture.bus.secure import POLICY_FILE, Policy

        if not name:
            print(
                "couture drape: --tls needs --name: the client's certificate in the secure directory", file=sys.stderr
            )
            return DrapeExit.USAGE
        writers = Policy.load(Path(bus.tls) / POLICY_FILE).writers
        if name not in writers:  # the session would drop its pattern without a word
            print(
                f"couture drape: {name!r} may not publish patterns in this session ({Path(bus.tls) / POLICY_FILE} "
                f"lists {', '.join(writers) or 'no writers'}); add it with `couture certs --out {bus.tls} "
                f"--nodes {name} --writers {name}`",
                file=sys.stderr,
            )
            return DrapeExit.USAGE
    if not verbose:
        # ezdxf and the supervisor log at INFO; the result lines say what matters
        logging.getLogger().setLevel(logging.WARNING)
    try:
        design = load_design(pattern)  # fail on a bad file before starting anything
        design = with_library_fabrics(design, fabric, panel_fabrics or {})
    except ValueError as e:
        print(f"couture drape: bad design: {e}", file=sys.stderr)
        return DrapeExit.BAD_DESIGN
    out_dir = Path(out)
    # the tolerances the solver node stops at, for the bars' scale only
    tol = dict(DEFAULT_TOL)
    progress = _DrapeProgress(tol)
    with ExitStack() as stack:
        if bus.connect:
            cfg = bus
        else:
            # the default graph without sensitivity (a one-shot drape makes no predictions,
            # and its refactorizations would take CPU from the solve), adjust and ui
            from couture.graph import load_graph

            graph = load_graph().with_solvers([solver])
            for kind in ("sensitivity", "adjust", "ui"):
                graph = graph.without(kind)
            if solver_max_seconds is not None:
                graph.set("solver", "max_seconds", repr(float(solver_max_seconds)))
            nodes = supervisor.graph_nodes(graph)
            child_log = None
            if not verbose:
                out_dir.mkdir(parents=True, exist_ok=True)
                child_log = out_dir / "nodes.log"
                child_log.write_bytes(b"")
            sup = stack.enter_context(
                supervisor.Supervisor(
                    supervisor.SupervisorConfig(
                        bus=bus, nodes=nodes, child_log=None if child_log is None else str(child_log)
                    )
                )
            )
            cfg = sup.child_bus
        client = stack.enter_context(Client(bus=cfg, name=name))
        stack.callback(progress.close)
        if not bus.connect:
            client.wait_nodes(["remesher", f"solver-{solver}"], timeout=min(30.0, timeout))
        gen = client.publish_pattern(design, name=Path(pattern).stem)
        print(
            f"[drape] {pattern}: design {client.design_id_of(gen)} (asks for generation {gen}), solver {solver}",
            file=sys.stderr,
            flush=True,
        )
        try:
            d = client.follow_drape(gen, timeout=timeout, on_drape=progress)
        except PatternRejected as e:
            progress.close()
            print(f"couture drape: bad design: {e}", file=sys.stderr)
            return DrapeExit.BAD_DESIGN
        except TimeoutError as e:
            progress.close()
            print(f"couture drape: timeout: {e}", file=sys.stderr)
            return DrapeExit.TIMEOUT
        progress.close()
        if "fine" not in progress.finals:  # joined after the fine result was already out
            print(f"[drape] fine: {_describe(d, tol['fine'])}", file=sys.stderr, flush=True)
        # the mesh of exactly this design (another client's may have come since)
        mesh = client.mesh_of(d.generation, "fine")
        if mesh is None or mesh.mesh_generation != d.mesh_generation or mesh.X.shape[0] != d.x.shape[0]:
            raise RuntimeError(
                f"drape/fine for generation {d.generation} (mesh {d.mesh_generation}, {d.x.shape[0]} vertices) "
                f"arrived but no matching mesh/fine (have "
                f"{None if mesh is None else (mesh.generation, mesh.mesh_generation, mesh.X.shape[0])})"
            )
        out_dir.mkdir(parents=True, exist_ok=True)
        write_obj(out_dir / "drape.obj", d.x.numpy(), mesh.tris.numpy(), mesh.X.numpy())
        shutil.copyfile(pattern, out_dir / "pattern.json")
        from couture.pattern import draft
        from couture.pattern.cutting import CutSpec
        from couture.pattern.io import export_dxf, export_pdf, export_svg

        drafted = draft(design)
        # pieces to cut: 1 cm seam allowances, 3 cm hems, notches, grain, labels
        cut = CutSpec(design_name=Path(pattern).stem, sheet_width=1.2)
        export_dxf(drafted, out_dir / "pattern.dxf", spec=cut)
        export_svg(drafted, out_dir / "pattern.svg", spec=cut)
        export_pdf(drafted, out_dir / "pattern.pdf", spec=cut)
        (out_dir / "drape.json").write_text(  # standard JSON: a non-finite residual is null
            dumps(
                {
                    "generation": d.generation,
                    "design_id": mesh.design_id,
                    "mesh_generation": d.mesh_generation,
                    "solver": d.solver,
                    "method": d.method,
                    "residual": d.residual,
                    "tolerance": tol["fine"],
                    "iterations": d.iterations,
                    "converged": d.converged,
                    "diagnosis": d.diagnosis,
                    "wall_time_s": d.wall_time_s,
                    "vertices": int(d.x.numpy().shape[0]),
                    "terms": list(d.terms),
                },
                indent=2,
            )
        )
        print(f"[drape] wrote {out_dir / 'drape.obj'}, drape.json and pattern.json/.dxf/.svg/.pdf", file=sys.stderr)
    if not d.converged:
        print(
            f"couture drape: not converged: fine residual {d.residual:.2e} (tolerance {tol['fine']:.0e}) after "
            f"{d.iterations} iterations, solver {d.solver} ({d.method}): {d.diagnosis or 'no diagnosis given'}",
            file=sys.stderr,
        )
        return DrapeExit.NOT_CONVERGED
    return DrapeExit.CONVERGED


def export_pattern(args: argparse.Namespace) -> int:
    """``couture export``: the pieces of a pattern file as DXF, SVG, PDF, tiled PDF."""
    from couture.pattern import draft_with_context
    from couture.pattern.cutting import CutSpec, cut_pieces
    from couture.pattern.io import export_dxf, export_pdf, export_pdf_tiled, export_svg, load_design

    logging.getLogger("ezdxf").setLevel(logging.WARNING)
    design = load_design(args.pattern)
    drafted, ctx = draft_with_context(design)
    widths = {}
    for item in args.allowance:
        key, eq, value = item.partition("=")
        try:
            widths[key] = float(value)
        except ValueError:
            raise ValueError(f"--allowance {item!r} is not SEGMENT=WIDTH (a width in metres)") from None
        if not eq or not key:
            raise ValueError(f"--allowance {item!r} is not SEGMENT=WIDTH (a width in metres)")
    name = args.name or Path(args.pattern).stem
    size = args.size
    if size is None:
        girths = [
            (k[0].upper(), ctx.params[f"{k}_girth"]) for k in ("bust", "waist", "hip") if f"{k}_girth" in ctx.params
        ]
        size = " ".join(f"{c}{v * 100:.0f}" for c, v in girths)
    spec = CutSpec(
        seam_allowance=args.seam_allowance,
        hem_allowance=args.hem_allowance,
        hem_segments=tuple(args.hem_segments),
        widths=widths,
        notch_spacing=args.notch_spacing,
        end_notches=not args.no_end_notches,
        group=not args.every_panel,
        design_name=name,
        size=size,
        sheet_width=args.sheet_width,
    )
    pieces = cut_pieces(drafted, spec)  # checks the spec before any file is written
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    stem = "".join(c if c.isalnum() or c in "_-." else "_" for c in name)
    written = []
    for fmt in dict.fromkeys(args.format):
        if fmt == "dxf":
            export_dxf(drafted, out / f"{stem}.dxf", units=args.units, spec=spec)
            written.append(f"{stem}.dxf")
        elif fmt == "svg":
            export_svg(drafted, out / f"{stem}.svg", spec=spec)
            written.append(f"{stem}.svg")
        elif fmt == "pdf":
            export_pdf(drafted, out / f"{stem}.pdf", spec=spec)
            written.append(f"{stem}.pdf")
        else:
            cols, rows = export_pdf_tiled(drafted, out / f"{stem}-{args.paper}.pdf", args.paper, spec=spec)
            written.append(f"{stem}-{args.paper}.pdf ({cols} x {rows} = {cols * rows} pages)")
    print(f"{args.pattern}: {len(pieces)} pieces to cut ({sum(p.quantity for p in pieces)} with copies)")
    for p in pieces:
        print(f"  {p.name}: {p.labels[-1]}, {len(p.notches)} notches, {len(p.drills)} drill holes")
    print(f"wrote into {out}: {', '.join(written)}")
    return 0


def adjust(args: argparse.Namespace) -> int:
    """``couture adjust``: see its --help."""
    from couture.adjust.pipeline import plot_case, write_outputs
    from couture.adjust.settings import DEFAULTS
    from couture.adjust.verdict import assess, body_for
    from couture.bus import bus_config_from_args
    from couture.client import adjust_on_bus, fit_on_bus, load_design, solver_session
    from couture.pattern.io import save_design

    design = load_design(args.pattern)
    edit, amount = ("hem", args.hem) if args.hem is not None else ("waist", args.waist)
    if not math.isfinite(amount) or amount == 0:
        raise ValueError(
            f"--{edit} {amount!r}: "
            + ("a nonzero length change [m] (negative shortens)" if edit == "hem" else "a nonzero girth change [m]")
        )
    vertices = args.vertices or design.resolution.coarse_vertices
    bus = bus_config_from_args(args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    solvers = args.solver or ([] if bus.connect else ["newton"])
    if not args.verbose:
        logging.getLogger().setLevel(logging.WARNING)  # ezdxf and the supervisor log at INFO

    def say(text: str) -> None:
        print(text, file=sys.stderr, flush=True)

    fitted = None
    fit: dict = {}  # adjust.json's design_fit: the fitted design's numbers, or why there is none
    with solver_session(solvers, bus if bus.connect else None, log_file=str(out / "nodes.log")) as (client, names):
        say(f"[adjust] solves go to {', '.join(names)}")
        case, counts = adjust_on_bus(
            client,
            names,
            design,
            edit,
            amount,
            vertices=vertices,
            name=Path(args.pattern).stem,
            settings=DEFAULTS.with_(
                start=args.start,
                updates=args.iters,
                stop_stretch=args.stop_stretch,
                gradient_steps=args.gradient_steps,
                stretch_weight=args.stretch_weight,
                max_solves=args.max_solves,
            ),
            equalize=not args.no_equalize,
            log=say,
        )
        verdict = assess(case, body=body_for(design))
        case.verdict = verdict
        if not args.no_fit:
            # what the adjust node publishes for this edit (couture.adjust.service.run_adjustment)
            try:
                fitted = fit_on_bus(
                    client, names, design, case, vertices=vertices, progress=lambda _s, _k, t: say(f"[adjust] {t}")
                )
            except ValueError as e:
                fit = {"error": str(e)}
                say(f"[adjust] no design.json: {e}")
    if fitted is not None:
        save_design(fitted.design, out / "design.json")
        p = fitted.projection
        fit = {
            "design": "design.json",
            "options": {k: [a, b] for k, (a, b) in p.changed.items()},
            "asked_m": amount,
            "achieved_m": fitted.achieved,
            "fit_rms_m": p.fit_rms_m,
            "fit_max_m": p.fit_max_m,
            "drapes": len(fitted.calibration),
            "calibration": fitted.calibration,
            "seconds": fitted.seconds,
        }
    write_outputs(case, out, extra={"design_fit": fit} if fit else None)
    plot_case(case, out / "adjust.png")
    s = case.summary()
    say(
        f"[adjust] {s['design']}: start ({s['start']['pattern']}): Hausdorff {s['start']['hausdorff_pct']:.2f} % of "
        f"height, stretch {s['start']['stretch']:.4f}; adjusted (iteration {s['adjusted']['iteration']}): "
        f"Hausdorff {s['adjusted']['hausdorff_pct']:.2f} %, stretch {s['adjusted']['stretch']:.4f}; "
        + (
            f"after {s['final']['gradient_steps_taken']} gradient steps: Hausdorff {s['final']['hausdorff_pct']:.2f} %, "
            f"stretch {s['final']['stretch']:.4f}; "
            if case.gradient
            else ""
        )
        + f"edit to pattern {s['timings_s']['edit_to_pattern']:.1f} s; solves per node {counts}; "
        f"seams differ by at most {s['seams']['max_mismatch_mm']['adjusted']:.2f} mm"
    )
    if fitted is not None:
        opts = ", ".join(f"{k} {a:.3f} -> {b:.3f}" for k, (a, b) in sorted(fitted.projection.changed.items()))
        say(
            f"[adjust] design.json (what the UI's adjust tool publishes): {opts}; outline fit "
            f"{1e3 * fitted.projection.fit_rms_m:.1f} mm RMS; its drape: {edit} {100 * fitted.achieved:+.1f} cm "
            f"({100 * amount:+.1f} cm asked)"
        )
    say(
        f"[adjust] wrote {out}/pattern.dxf, .svg, .pdf, panels.json, drape_*.obj, adjust.json, adjust.png"
        + (", design.json" if fitted is not None else "")
    )
    say(f"[adjust] {verdict.text()}")
    return 0 if verdict.met else 3


def write_obj(path: Path, x, tris, uv=None) -> None:
    """Wavefront OBJ: positions [m], optional texture coordinates (the 2D pattern [m]), faces."""
    with open(path, "w") as f:
        f.write("# couture drape, units: metres\n")
        for p in x:
            f.write(f"v {p[0]:.7g} {p[1]:.7g} {p[2]:.7g}\n")
        if uv is not None:
            for q in uv:
                f.write(f"vt {q[0]:.7g} {q[1]:.7g}\n")
        for t in tris + 1:
            if uv is not None:
                f.write(f"f {t[0]}/{t[0]} {t[1]}/{t[1]} {t[2]}/{t[2]}\n")
            else:
                f.write(f"f {t[0]} {t[1]} {t[2]}\n")


if __name__ == "__main__":
    sys.exit(main())
