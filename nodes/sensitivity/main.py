"""The sensitivity node (SC §4, §7.2): instant 3D response to 2D and 3D edits.

A thin adapter over :class:`couture.sensitivity.Predictor`:

- a new fine mesh or a final solver drape on it -> the predictor's equilibrium;
  the stiffness is refactored in idle time (worker thread);
- edit *press* -> wait for the remesher's Ψ for this gesture (the mesh/fine
  re-send carrying ``psi_edit_id``); 2D: Ψ of the dragged element; 3D tug: Ψ of
  ``param:<name>`` (dX/dg), and the picked point's sensitivity s = ∂x/∂g;
- edit *drag* -> ``drape/predicted`` at pointer rate (GMLS once samples exist,
  linear before); its error estimate (the prediction's relative force residual)
  follows in idle time as a re-send of the same prediction;
- pointer *pause* -> a short solve at the current design point from the
  prediction, added to the GMLS cache (SC's progressive nonlinear model);
- *release* -> the final prediction (the solver's warm start); for a 3D tug
  also the new design (sloper parameter g0 + Δg) as a ``pattern`` message.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass, field

import msgspec
import numpy as np

from couture.bus import BusConfig, Node
from couture.bus.worker import DesignLog, LatestWorker
from couture.cloth.model import ClothModel
from couture.pattern import SLOPERS
from couture.sensitivity import Predictor, drag_to_param
from couture.solvers import get_solver
from couture.solvers.service import scene_from_design
from schemas import DrapeMsg, EditMsg, MeshMsg, PatternMsg
from schemas.convert import msg_to_mesh
from schemas.design import Sloper

log = logging.getLogger("sensitivity")


@dataclass
class Config:
    bus: BusConfig = field(default_factory=BusConfig)
    name: str = "sensitivity"
    """node name, unique in the session (liveliness key status/<name>)"""
    method: str = "gmls"
    """'gmls', 'mls' or 'linear'"""
    pause_s: float = 0.3
    """[s] without pointer motion before the idle solve that enriches the cache"""
    enrich_seconds: float = 2.0
    """[s] budget of one idle solve"""
    enrich_tol: float = 1e-3
    """relative residual the idle solve aims for"""


@dataclass
class Gesture:
    edit_id: str
    element: str
    generation: int
    mesh_generation: int
    param: str = ""
    picked_vertex: int = -1
    view_proj: np.ndarray | None = None
    viewport: tuple[int, int] = (1, 1)
    ready: bool = False
    s_point: np.ndarray | None = None
    d: np.ndarray = field(default_factory=lambda: np.zeros(2))
    last_motion: float = 0.0
    enriched_at: np.ndarray | None = None


def main(config: Config) -> None:
    predictor = Predictor(method=config.method, error_estimate=False)
    with Node(config.name, config.bus, kind="sensitivity") as node:
        bus = node.bus
        pred_pub = bus.publisher("drape/predicted", DrapeMsg)
        pattern_pub = bus.publisher("pattern", PatternMsg)
        idle = LatestWorker("sensitivity-idle", on_error=node.error)
        edits = LatestWorker("sensitivity-edit", on_error=node.error)
        lock = threading.RLock()
        designs = DesignLog()
        st = {"mesh": None, "mesh_generation": -1, "generation": -1, "model": None,
              "gesture": None}

        # -- inputs -----------------------------------------------------------
        def on_pattern(msg: PatternMsg) -> None:
            designs.add(msg.generation, msg.design)
            with lock:
                parked = st.pop("parked", None)
            if parked is not None:  # a mesh that arrived before its pattern
                idle.submit("mesh", parked)

        def on_mesh(msg: MeshMsg) -> None:
            if msg.level != "fine":
                return
            if msg.psi is not None and msg.psi_edit_id:
                psi = msg.psi.numpy().copy()
                edits.submit("press", lambda: press_with(msg.psi_edit_id, msg.mesh_generation, psi))
                return
            if msg.mesh_generation == st["mesh_generation"]:
                return
            mesh = msg_to_mesh(msg)

            def job() -> None:
                design = designs.at(msg.generation)
                if design is None:
                    with lock:
                        st["parked"] = job
                    return
                model = ClothModel(mesh, design.fabric, scene_from_design(design))
                with lock:
                    st.update(mesh=mesh, mesh_generation=msg.mesh_generation, generation=msg.generation, model=model)
                log.info("mesh generation %d: %d vertices", msg.mesh_generation, mesh.n_vertices)
            idle.submit("mesh", job)

        def on_drape(msg: DrapeMsg) -> None:
            if not msg.final or msg.level != "fine":
                return
            x = msg.x.numpy().astype(np.float64)

            def job() -> None:
                with lock:
                    model = st["model"]
                    if model is None or msg.mesh_generation != st["mesh_generation"] or x.shape != (model.n, 3):
                        return
                    if st["gesture"] is not None:
                        return  # keep the equilibrium the gesture started from
                predictor.set_equilibrium(model, x)
                info = predictor.refactor()
                node.count("refactors")
                log.info("refactored at mesh generation %d in %.0f ms (%s)", msg.mesh_generation,
                         1e3 * info.refactor_s, info.backend)
            idle.submit("equilibrium", job)

        def on_edit(msg: EditMsg) -> None:
            if msg.phase == "press":
                g = Gesture(edit_id=msg.edit_id, element=msg.element, generation=msg.generation,
                            mesh_generation=st["mesh_generation"], param=msg.param,
                            picked_vertex=msg.picked_vertex,
                            view_proj=None if msg.view_proj is None else msg.view_proj.numpy().copy(),
                            viewport=tuple(msg.viewport_px or (1, 1)), last_motion=time.monotonic())
                with lock:
                    st["gesture"] = g
                node.count("presses")
                return
            g = st["gesture"]
            if g is None or g.edit_id != msg.edit_id:
                return
            d_raw = msg.d.numpy().copy()
            if msg.phase == "drag":
                g.last_motion = time.monotonic()
                edits.submit("drag", lambda: predict(g, d_raw, final=False))
            else:
                edits.submit("drag", lambda: release(g, d_raw))

        # -- edit work (edits worker) -----------------------------------------
        def press_with(edit_id: str, mesh_generation: int, psi: np.ndarray) -> None:
            g = st["gesture"]
            if g is None or g.edit_id != edit_id:
                return
            if predictor.model is None or predictor.model.n != psi.shape[0]:
                node.error(f"edit {edit_id}: no equilibrium on this mesh yet; no prediction")
                return
            t0 = time.perf_counter()
            S = predictor.press(psi)
            if g.picked_vertex >= 0:
                g.s_point = S[g.picked_vertex, :, 0]
            g.ready = True
            node.count("press_columns")
            log.info("press %s on %s: columns in %.0f ms", edit_id, g.element or g.param, 1e3 * (time.perf_counter() - t0))

        def design_point(g: Gesture, d_raw: np.ndarray) -> np.ndarray | None:
            if g.picked_vertex < 0:
                return d_raw
            if g.s_point is None or g.view_proj is None:
                return None
            x_point = predictor.x_eq[g.picked_vertex]
            r = drag_to_param(g.s_point, g.view_proj, g.viewport, x_point, d_raw)
            if r.ignored:
                node.count("insensitive_drags")
            return np.array([float(r.dg[0]), 0.0])

        def predict(g: Gesture, d_raw: np.ndarray, *, final: bool) -> np.ndarray | None:
            if not g.ready:
                return None
            d = design_point(g, d_raw)
            if d is None:
                return None
            g.d = d
            p = predictor.drag(d, error_estimate=False)
            publish(g, p.x, d, p.method, None, final)
            node.count("predictions")
            idle.submit("error", lambda: estimate(g, p))
            return p.x

        def publish(g: Gesture, x: np.ndarray, d: np.ndarray, method: str, err: float | None, final: bool) -> None:
            pred_pub.put(DrapeMsg(level="predicted", mesh_level="fine", mesh_generation=g.mesh_generation,
                                  x=x.astype(np.float32), d=d, edit_id=g.edit_id, method=method,
                                  error_estimate=err, generation=g.generation, final=True,
                                  diagnosis="release" if final else ""))

        def estimate(g: Gesture, p) -> None:
            if st["gesture"] is not g or predictor.last is not p:
                return  # a newer prediction exists
            err = predictor.error_of(p.x, p.d)
            publish(g, p.x, p.d, p.method, err, False)

        def release(g: Gesture, d_raw: np.ndarray) -> None:
            x = predict(g, d_raw, final=True)
            with lock:
                st["gesture"] = None
            if x is None or g.picked_vertex < 0 or not g.param:
                return
            # a 3D tug ends with the new design: the sloper parameter moved by Δg
            design = designs.at(g.generation)
            if design is None:
                return
            opt = {o.name: o for o in SLOPERS[design.sloper.kind].options}.get(g.param)
            if opt is None:
                node.error(f"3D tug: sloper {design.sloper.kind!r} has no option {g.param!r}")
                return
            params = dict(design.sloper.params)
            g0 = params.get(g.param, opt.default)
            params[g.param] = float(np.clip(g0 + g.d[0], opt.min, opt.max))
            new = msgspec.structs.replace(design, sloper=Sloper(kind=design.sloper.kind, params=params))
            gen = max(designs.latest_generation, g.generation) + 1
            pattern_pub.put(PatternMsg(design=new, generation=gen, source=config.name, name="3D tug"))
            log.info("3D tug: %s %.4f -> %.4f (generation %d)", g.param, g0, params[g.param], gen)

        # -- idle enrichment: a short solve where the pointer pauses ------------
        solver = get_solver("newton")

        def enrich(g: Gesture) -> None:
            if st["gesture"] is not g or predictor.last is None:
                return
            d = g.d.copy()
            model_d = predictor.model_at(predictor.model, predictor.rest_at(d))
            r = solver.solve(model_d, predictor.last.x, tol=config.enrich_tol, max_seconds=config.enrich_seconds,
                             callback=lambda *_: st["gesture"] is not g or
                             time.monotonic() - g.last_motion < config.pause_s)
            if st["gesture"] is not g or not np.isfinite(r.residual):
                return
            if r.residual < (predictor.last.error_estimate if np.isfinite(predictor.last.error_estimate) else np.inf):
                predictor.add_sample(d, r.x)
                g.enriched_at = d
                node.count("samples")
                log.info("cache sample at d=%s (residual %.1e) -> %d samples", np.round(d, 4), r.residual,
                         len(predictor.cache))
                p = predictor.drag(d, error_estimate=False)
                publish(g, p.x, d, p.method, r.residual, False)

        def tick() -> None:
            g = st["gesture"]
            if (g is not None and g.ready and time.monotonic() - g.last_motion > config.pause_s
                    and (g.enriched_at is None or not np.array_equal(g.enriched_at, g.d))
                    and not idle.pending("enrich")):
                g.enriched_at = g.d.copy()
                idle.submit("enrich", lambda: enrich(g))

        bus.subscribe("pattern", on_pattern)
        bus.subscribe("mesh/fine", on_mesh)
        bus.subscribe("drape/fine", on_drape)
        bus.subscribe("edit", on_edit)
        try:
            node.run(idle=tick, period_s=0.05)
        finally:
            edits.close()
            idle.close()
