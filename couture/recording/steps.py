"""The steps of a golden case, driven through the bus (couture.recording.golden).

A case's ``steps`` is a list of one-key objects, run in order against live
nodes (a supervisor's children) by a :class:`Driver`:

``{"design": FILE_OR_PATCH}`` or ``{"design": [FILE, PATCH, ...]}``
    publish a design (a pattern file, or a patch merged into the current
    design; a list applies its parts in order) and wait for its final drape/fine.
``{"drag": {"element": "cv:gore0:hem:0", "d": [0, 0.02], "moves": 12, "rate_hz": 30, "kill_solver_after": 4}}``
    a 2D drag of a pattern handle, as the UI sends it: once predictions are
    ready, a press, ``moves`` drags at ``rate_hz`` (pointer rate) reaching
    ``d`` [m], a release; then the design ``apply_edit(design, element, d)``
    committed as a pattern (what the UI does on release), waited for.
    ``kill_solver_after``: SIGKILL the solver node's process group after
    that many drags (the supervisor restarts it); the drag goes on at
    pointer rate, the pointer is held at ``d`` until the restarted solver
    has published a final drape/fine of the current design again (it
    resumes from the latest pattern and mesh), then released.
``{"tug": {"param": "length", "px": [0, 40], "moves": 12, "rate_hz": 30}}``
    a 3D tug on the hem: press on the lowest front vertex of the current
    fine drape (camera :func:`camera`, 800x800 px viewport), drags reaching
    ``px`` screen pixels, release; the sensitivity node publishes the tugged
    design, which is waited for.
``{"tryon": {"op": "drag", "panel": "gore1", "angle": 0.3, "vector": [0, -0.05, 0], "seam": -1, "sewn": true}}``
    a try-on op (``couture/tryon/v1``, couture.tryon; the keys other than
    ``op`` are optional) on the current design; waits for the solver's
    final drape/fine answering it (its ``edit_id`` is the op's ``op_id``).
``{"switch_solver": "kinetic"}``
    stop the solver node(s) and start ``solver-<name>``; wait until it has
    published a final drape/fine of the current design (it resumes from the
    latest pattern and mesh on its own).

``make`` (``Driver(replay=None)``) makes the inputs; ``check`` replays the
golden's inputs byte for byte instead (``replay=GoldenInputs``): each pattern
that a client published (not the sensitivity node's tug designs, which the
live node makes again) and each gesture's edits at their recorded offsets
from the press (pointer rate), with the same control actions (solver switch,
kill) at the same points. Every wait is lockstep (a design's final drape
before the next input), so outputs do not depend on the machine's speed.
"""

from __future__ import annotations

import threading
import time
import uuid
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from schemas.design import Design
from schemas.messages import DrapeMsg, EditMsg, MeshMsg, PatternMsg, TryOnMsg, decode

STEP_KINDS = ("design", "drag", "tug", "tryon", "switch_solver")
GESTURES = ("drag", "tug")
VIEWPORT = [800, 800]
SENSITIVITY = "sensitivity"


def camera() -> np.ndarray:
    """View-projection (world [m] -> clip) of a camera 2.6 m in front of the
    mannequin (+z) looking at it, y up (the UI's initial view)."""
    f, near, far = 1.0 / np.tan(np.deg2rad(25.0)), 0.1, 10.0
    proj = np.array(
        [[f, 0, 0, 0], [0, f, 0, 0], [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)], [0, 0, -1, 0]]
    )
    view = np.eye(4)
    view[:3, 3] = [0.0, -0.15, -2.6]
    return proj @ view


def validate(steps: list, where: str) -> None:
    """A clear error naming the step for a malformed step list."""
    for i, st in enumerate(steps):
        if not isinstance(st, dict) or len(st) != 1 or next(iter(st)) not in STEP_KINDS:
            raise ValueError(f"{where}: step {i} must be one of {{{', '.join(STEP_KINDS)}: ...}}, got {st!r}")
        kind, arg = next(iter(st.items()))
        if kind in GESTURES:
            need = {"drag": {"element", "d"}, "tug": {"param", "px"}}[kind]
            allowed = need | {"moves", "rate_hz", "kill_solver_after"}
            if not isinstance(arg, dict) or not need <= set(arg) or set(arg) - allowed:
                raise ValueError(f"{where}: step {i} ({kind}) needs {sorted(need)}, allows {sorted(allowed)}: {arg!r}")
        if kind == "tryon":
            allowed = {"op", "panel", "vector", "angle", "seam", "sewn"}
            if not isinstance(arg, dict) or "op" not in arg or set(arg) - allowed:
                raise ValueError(f"{where}: step {i} (tryon) needs 'op', allows {sorted(allowed)}: {arg!r}")


@dataclass
class GoldenInputs:
    """A golden recording's inputs, split the way the steps consume them."""

    patterns: list[bytes] = field(default_factory=list)
    """patterns a client published (not the sensitivity node's tug designs), in order"""
    gestures: list[list[tuple[int, bytes]]] = field(default_factory=list)
    """per gesture (edit_id, in order of its press): (ns since its first message, payload)"""
    tryons: list[bytes] = field(default_factory=list)
    """try-on ops, in order"""

    @classmethod
    def read(cls, path: Any) -> "GoldenInputs":
        from couture.recording.mcapio import read_session

        out = cls()
        by_id: dict[str, list[tuple[int, bytes]]] = {}
        for rec in read_session(str(path), ["pattern", "edit", "tryon"]):
            if rec.topic == "tryon":
                out.tryons.append(rec.data)
            elif rec.topic == "pattern":
                if decode(rec.data, PatternMsg).source != SENSITIVITY:
                    out.patterns.append(rec.data)
            else:
                e = decode(rec.data, EditMsg)
                if e.edit_id not in by_id:
                    by_id[e.edit_id] = []
                    out.gestures.append(by_id[e.edit_id])
                by_id[e.edit_id].append((rec.log_time, rec.data))
        for g in out.gestures:
            t0 = g[0][0]
            g[:] = [(t - t0, data) for t, data in g]
        return out


@dataclass
class StepLog:
    """What a run did, for the report (never compared)."""

    lines: list[str] = field(default_factory=list)
    predictions_after_kill: list[int] = field(default_factory=list)
    """per kill: predictions of that gesture received after the SIGKILL"""
    tug_params: list[float] = field(default_factory=list)
    """per tug: the tugged design's parameter value"""


class Driver:
    """Runs a case's steps on live nodes (module doc)."""

    def __init__(self, case: Any, sup: Any, client: Any, replay: GoldenInputs | None = None, timeout: float = 120.0):
        from couture import supervisor

        self.case, self.sup, self.client, self.replay = case, sup, client, replay
        self.timeout = timeout
        self.supervisor = supervisor
        self.log = StepLog()
        self.design: Design | None = None
        self.generation = 0
        self.solvers = [f"solver-{s}" for s in case.solvers]
        self._cv = threading.Condition()
        self._given: dict[str, int] = {}
        """design identity -> the generation the remesher gave it"""
        self._designs: dict[str, Design] = {}
        self._tugs: list[PatternMsg] = []
        self._next_pattern = 0
        self._next_gesture = 0
        self._next_tryon = 0
        bus = client.bus
        self.pattern_pub = bus.publisher("pattern", PatternMsg)
        self.edit_pub = bus.publisher("edit", EditMsg)
        self.tryon_pub = bus.publisher("tryon", TryOnMsg)
        bus.subscribe("pattern", self._on_pattern, PatternMsg)
        bus.subscribe("mesh/fine", self._on_mesh, MeshMsg)

    # -- bus callbacks
    def _on_pattern(self, msg: PatternMsg) -> None:
        with self._cv:
            self._designs[msg.identity()] = msg.design
            if msg.source == SENSITIVITY:
                self._tugs.append(msg)
            self._cv.notify_all()

    def _on_mesh(self, msg: MeshMsg) -> None:
        if msg.design_id:
            with self._cv:
                self._given[msg.design_id] = msg.generation
                self._cv.notify_all()

    def _wait(self, what: str, cond: Any, timeout: float | None = None) -> Any:
        deadline = time.monotonic() + (timeout or self.timeout)
        with self._cv:
            while not (v := cond()):
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f"golden {self.case.name}: {what} not within {timeout or self.timeout:g} s")
                self._cv.wait(min(left, 0.1))
            return v

    def say(self, text: str) -> None:
        import sys

        self.log.lines.append(text)
        print(f"[golden] {self.case.name}: {text}", file=sys.stderr, flush=True)

    # -- designs
    def _publish(self, design: Design | None, step: int) -> DrapeMsg:
        """Publish the step's design (make) or the golden's next client pattern
        (check); wait for its final drape/fine; it becomes the current design."""
        if self.replay is None:
            assert design is not None
            msg = PatternMsg(
                design=design,
                generation=max(self.generation, self.client.current_generation) + 1,
                design_id=uuid.uuid4().hex,
                source="golden",
                name=f"{self.case.name}:{step}",
            )
            self.pattern_pub.wait_matching(5.0)
            self.pattern_pub.put(msg)
        else:
            if self._next_pattern >= len(self.replay.patterns):
                raise ValueError(f"golden {self.case.name}: step {step} needs a pattern the golden does not hold")
            data = self.replay.patterns[self._next_pattern]
            self._next_pattern += 1
            msg = decode(data, PatternMsg)
            self.pattern_pub.put_raw(data)
        return self._settle(msg.identity(), step)

    def _settle(self, identity: str, step: int) -> DrapeMsg:
        gen = self._wait(f"step {step}: a mesh of design {identity}", lambda: self._given.get(identity))
        drape = self.client.wait_drape("fine", generation=gen, timeout=self.timeout, final=True)
        with self._cv:
            self.design = self._designs.get(identity, self.design)
        self.generation = gen
        self.say(
            f"step {step}: generation {gen} from {drape.solver}: residual {drape.residual:.2e} "
            + ("converged" if drape.converged else drape.diagnosis)
        )
        return drape

    def design_step(self, step: int, entry: Any) -> None:
        design = None
        if self.replay is None:
            design = resolve_design(self.case, self.design, entry)
        self._publish(design, step)

    # -- solvers
    def _resumed(self, solver: str, since_ns: int, step: int, what: str) -> DrapeMsg:
        """Wait for ``solver``'s final drape/fine of the current design stamped after ``since_ns``."""

        def find() -> DrapeMsg | None:
            return next(
                (
                    d
                    for d in reversed(self.client.drapes("fine"))
                    if d.solver == solver and d.final and d.generation == self.generation and d.stamp_ns > since_ns
                ),
                None,
            )

        deadline = time.monotonic() + self.timeout
        while (d := find()) is None:
            if time.monotonic() > deadline:
                raise TimeoutError(
                    f"golden {self.case.name}: step {step}: {solver} published no final drape/fine of generation "
                    f"{self.generation} after {what} within {self.timeout:g} s"
                )
            time.sleep(0.05)
        self.say(f"step {step}: {solver} resumed generation {self.generation} after {what} (residual {d.residual:.2e})")
        return d

    def switch_solver(self, step: int, name: str) -> None:
        t = time.time_ns()
        for s in self.solvers:
            self.sup.stop_node(s)
        new = f"solver-{name}"
        self.sup.start_node(self.supervisor.NodeSpec(new, "nodes.solver", ["--solver", name]))
        self.solvers = [new]
        self.client.wait_nodes([new], timeout=60)
        self._resumed(new, t, step, "the switch")

    # -- gestures
    def _gesture_messages(self, step: int, kind: str, arg: dict) -> list[tuple[int, bytes]]:
        """(ns after the press, payload) of the gesture's press, drags and release."""
        if self.replay is not None:
            if self._next_gesture >= len(self.replay.gestures):
                raise ValueError(f"golden {self.case.name}: step {step} needs a gesture the golden does not hold")
            g = self.replay.gestures[self._next_gesture]
            self._next_gesture += 1
            return g
        moves, rate = int(arg.get("moves", 12)), float(arg.get("rate_hz", 30.0))
        edit_id = f"{self.case.name}-{step}"  # the same in every make: changes() can match its predictions
        if kind == "drag":
            end = np.asarray(arg["d"], np.float64)
            common: dict[str, Any] = dict(element=arg["element"], dofs=["x", "y"])
        else:
            end = np.asarray(arg["px"], np.float64)
            x = self.client.wait_drape("fine", generation=self.generation, final=True, timeout=5).x.numpy()
            hem = int(np.argmin(x[:, 1] - 0.1 * x[:, 2]))  # low, in front
            common = dict(
                element="",
                param=arg["param"],
                picked_vertex=hem,
                view_proj=camera(),
                viewport_px=VIEWPORT,
                dofs=[arg["param"]],
            )
        from schemas.arrays import Array
        from schemas.messages import encode

        def msg(phase: str, d: np.ndarray) -> bytes:
            m = dict(common)
            vp = m.pop("view_proj", None)
            return encode(
                EditMsg(
                    edit_id=edit_id,
                    phase=phase,  # type: ignore[arg-type]
                    d=Array.from_numpy(d),
                    generation=self.generation,
                    view_proj=None if vp is None else Array.from_numpy(vp),
                    **m,
                )
            )

        dt = int(1e9 / rate)
        out = [(0, msg("press", np.zeros(2)))]
        out += [(k * dt, msg("drag", end * k / moves)) for k in range(1, moves + 1)]
        out.append(((moves + 1) * dt, msg("release", end)))
        return out

    def gesture(self, step: int, kind: str, arg: dict) -> None:
        self.client.wait_predictions_ready(timeout=self.timeout, generation=self.generation)
        with self._cv:
            n_tugs = len(self._tugs)
        msgs = self._gesture_messages(step, kind, arg)
        kill_after = arg.get("kill_solver_after")
        edit = decode(msgs[0][1], EditMsg)
        t0 = time.monotonic()
        drags = 0
        killed_ns = 0
        for offset, data in msgs:
            phase = decode(data, EditMsg).phase
            if phase == "release" and killed_ns:
                # the pointer held still until the restarted solver is back with its drape
                self._resumed(self.solvers[0], killed_ns, step, "the SIGKILL")
            delay = t0 + offset / 1e9 - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            self.edit_pub.put_raw(data)
            if phase == "drag":
                drags += 1
                if kill_after is not None and drags == int(kill_after):
                    killed_ns = time.time_ns()
                    pid = self.sup.kill_node(self.solvers[0])
                    self.say(f"step {step}: SIGKILL {self.solvers[0]} (pid {pid}) after drag {drags}")
        release = decode(msgs[-1][1], EditMsg)
        preds = self._wait(
            f"step {step}: the release prediction of edit {edit.edit_id}",
            lambda: [
                d for d in self.client.drapes("predicted") if d.edit_id == edit.edit_id and d.diagnosis == "release"
            ],
        )
        mine = [d for d in self.client.drapes("predicted") if d.edit_id == edit.edit_id]
        if killed_ns:
            self.log.predictions_after_kill.append(sum(d.stamp_ns > killed_ns for d in mine))
        self.say(f"step {step}: {kind} {edit.edit_id}: {len(mine)} predictions, release at d={release.d.numpy()}")
        del preds
        if kind == "drag":
            design = None
            if self.replay is None:
                from couture.pattern.edit import apply_edit

                assert self.design is not None
                design = apply_edit(self.design, release.element, release.d.numpy())
            self._publish(design, step)
        else:
            tug = self._wait(
                f"step {step}: the sensitivity node's design for tug {edit.edit_id}",
                lambda: self._tugs[n_tugs] if len(self._tugs) > n_tugs else None,
            )
            self.log.tug_params.append(float(tug.design.sloper.params.get(arg["param"], float("nan"))))
            self._settle(tug.identity(), step)

    # -- try-on
    def tryon(self, step: int, arg: dict) -> None:
        """Publish a try-on op (make) or the golden's next one (check); wait for
        the final drape/fine answering it."""
        if self.replay is None:
            self.tryon_pub.wait_matching(5.0)
            msg = self.client.send_tryon(
                arg["op"],
                str(arg.get("panel", "")),
                vector=arg.get("vector"),
                angle=float(arg.get("angle", 0.0)),
                seam=int(arg.get("seam", -1)),
                sewn=bool(arg.get("sewn", True)),
                op_id=f"{self.case.name}-{step}",
                generation=self.generation,
            )
        else:
            if self._next_tryon >= len(self.replay.tryons):
                raise ValueError(f"golden {self.case.name}: step {step} needs a try-on op the golden does not hold")
            data = self.replay.tryons[self._next_tryon]
            self._next_tryon += 1
            msg = decode(data, TryOnMsg)
            self.tryon_pub.put_raw(data)
        d = self.client.wait_tryon(msg.op_id, "fine", timeout=self.timeout)
        self.say(
            f"step {step}: try-on {msg.op} {msg.panel or ''} -> residual {d.residual:.2e} "
            + ("converged" if d.converged else d.diagnosis)
        )

    def run(self, steps: list) -> StepLog:
        for i, st in enumerate(steps):
            kind, arg = next(iter(st.items()))
            if kind == "design":
                self.design_step(i, arg)
            elif kind == "switch_solver":
                self.switch_solver(i, arg)
            elif kind == "tryon":
                self.tryon(i, arg)
            else:
                self.gesture(i, kind, arg)
        return self.log


def resolve_design(case: Any, current: Design | None, entry: Any) -> Design:
    """A design step's design: a pattern file (relative to the case file or
    to the examples) or a patch merged into the current design."""
    import msgspec

    from couture.pattern.io import EXAMPLES, load_design

    design = current
    for part in entry if isinstance(entry, list) else [entry]:
        if isinstance(part, str):
            f = case.path.parent / part
            design = load_design(f if f.exists() else EXAMPLES / part)
        else:
            base = msgspec.to_builtins(design if design is not None else Design())
            design = msgspec.convert(_merge(base, part), Design)
    assert design is not None
    return design


def _merge(base: dict, patch: dict) -> dict:
    """``base`` with ``patch`` merged in, nested dicts key by key (a design step's patch)."""
    out = dict(base)
    for k, v in patch.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out
