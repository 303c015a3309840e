"""Bodies for given measurements, from the Anny parametric human model.

Anny (NAVER LABS, https://github.com/naver/anny; code Apache 2.0, its
MakeHuman-derived shape assets CC0 1.0) evaluates the same "notoes" template
topology as the default mannequin for shape parameters. :func:`fit_body`
solves for the parameters that give a body the requested ISO 8559-1
measurements, as this package reads them back (:mod:`couture.bodies.measure`):

- phenotypes ``height`` and ``weight`` (stature, overall girth), the other
  phenotypes (gender, age, muscle, proportions) held at Anny's neutral 0.5;
- MakeHuman's measurement targets ``measure-bust-circ-incr``,
  ``measure-waist-circ-incr``, ``measure-hips-circ-incr`` and
  ``upperlegs-height-incr`` (inside leg length), each in [-1, 1].

Damped Gauss-Newton on the five residuals, the Jacobian by autograd through
Anny and through the girths (each girth is the perimeter of the hull of
edge-plane crossings, differentiable in the vertices at a fixed section height;
the section heights are re-found every step, which the envelope theorem
allows for a smallest/largest girth).

Needs the optional extra ``couture[bodies]`` (``anny``, and the CPU PyTorch:
``pip install torch==2.13.0`` first, then ``pip install -e .[bodies]``).
Only :func:`make_graded` writes assets; the shipped ones were made by
``couture bodies make``.
"""

from __future__ import annotations

import json
import shutil
import sys
import time
from functools import lru_cache
from pathlib import Path
from typing import Callable

import numpy as np

from couture.bodies import BODIES_DIR, DEFAULT_FLOOR_Y, SIZE_TABLE, SIZE_TABLE_SOURCE, write_obj
from couture.bodies.measure import MEASURES, landmarks, measure

PHENOTYPES = ("height", "weight")
LOCAL_CHANGES = (
    "measure-bust-circ-incr",
    "measure-waist-circ-incr",
    "measure-hips-circ-incr",
    "upperlegs-height-incr",
)
PARAMS = PHENOTYPES + LOCAL_CHANGES
TOPOLOGY = "notoes"


def anny_available() -> bool:
    """Whether the optional extra (anny and PyTorch) is installed."""
    import importlib.util

    return all(importlib.util.find_spec(m) is not None for m in ("anny", "torch"))


def make_warped(
    out: Path, name: str, target: dict[str, float], write_sections: Callable[[Path, Path], None] | None = None
) -> dict:
    """Write the body ``name`` of measurements ``target`` [m] made without Anny
    (couture.bodies.warp: the nearest shipped body warped to them) to ``out``:
    <name>.obj, <name>.sections.npz (``write_sections``) and its bodies.json entry."""
    from couture.bodies import warp_to

    if name == "default" or not name.replace("_", "").replace("-", "").isalnum():
        raise ValueError(f"body name {name!r}: use letters, digits, '-' or '_', and not 'default'")
    r = warp_to(target)
    out.mkdir(parents=True, exist_ok=True)
    obj = out / f"{name}.obj"
    write_obj(
        obj,
        r.vertices,
        r.faces,
        f"couture body {name!r}: the shipped body {r.template!r} warped to {target} [m] by couture.bodies.warp"
        "\n(numpy/scipy; not a body scan); metres, y up, facing +z.",
    )
    if write_sections is not None:
        write_sections(obj, out / f"{name}.sections.npz")
    index_path = out / "bodies.json"
    index = json.loads(index_path.read_text()) if index_path.exists() else {"bodies": {}}
    index["bodies"][name] = {
        "requested": target,
        "measured": {k: round(v, 5) for k, v in r.measured.items()},
        "method": f"warp of {r.template!r} (couture.bodies.warp), {r.iterations} iterations, {r.seconds:.1f} s",
    }
    index_path.write_text(json.dumps(index, indent=2) + "\n")
    return index


def _require():
    try:
        import anny
        import torch
    except ImportError as e:  # pragma: no cover - depends on the extra
        raise RuntimeError(
            "bodies for measurements need the optional extra: pip install torch==2.13.0 (CPU build) "
            "then pip install 'couture[bodies]'"
        ) from e
    return anny, torch


@lru_cache(maxsize=1)
def anny_model():
    anny, torch = _require()
    return anny.Anny(topology=TOPOLOGY, local_changes="default").to(dtype=torch.float64)


def _vertices(theta):
    """Anny rest vertices for parameters theta (len(PARAMS),) in couture axes:
    x right, y up (Anny's z), z front (Anny's -y), feet at DEFAULT_FLOOR_Y."""
    _, torch = _require()
    model = anny_model()
    ph = {k: torch.full((1,), 0.5, dtype=torch.float64) for k in model.phenotype_labels}
    for i, k in enumerate(PHENOTYPES):
        ph[k] = theta[i : i + 1]
    lc = {k: theta[len(PHENOTYPES) + i : len(PHENOTYPES) + i + 1] for i, k in enumerate(LOCAL_CHANGES)}
    V = model(phenotype_kwargs=ph, local_changes_kwargs=lc)["rest_vertices"][0]
    V = torch.stack([V[:, 0], V[:, 2], -V[:, 1]], dim=1)
    return V - torch.stack([V[:, 0].new_zeros(()), V[:, 1].min() - DEFAULT_FLOOR_Y, V[:, 0].new_zeros(())])


def faces() -> np.ndarray:
    return np.asarray(anny_model().faces, dtype=np.int64)


def _measures_torch(V, F):
    """The five MEASURES of vertices V (torch, differentiable) at the landmark
    sections found on V's current values."""
    _, torch = _require()
    lm, _, crotch_edge = landmarks(V.detach().numpy(), F)

    def girth(sec):
        e = torch.as_tensor(sec.edges)
        a, b = V[e[:, 0]], V[e[:, 1]]
        t = (sec.y - a[:, 1]) / (b[:, 1] - a[:, 1])
        p = a + t[:, None] * (b - a)
        q = p[:, [0, 2]]
        return torch.linalg.norm(q - torch.roll(q, 1, dims=0), dim=1).sum()

    a, b = V[int(crotch_edge[0])], V[int(crotch_edge[1])]
    crotch_y = a[1] + (0.0 - a[0]) / (b[0] - a[0]) * (b[1] - a[1])
    floor = V[:, 1].min()
    return torch.stack([V[:, 1].max() - floor, girth(lm.bust), girth(lm.waist), girth(lm.hip), crotch_y - floor])


def fit_body(
    target: dict[str, float], tol: float = 0.002, max_iter: int = 25, verbose: bool = True
) -> tuple[np.ndarray, np.ndarray, dict[str, float], dict[str, float]]:
    """(vertices, faces, parameters, measured) of the Anny body whose measured
    MEASURES [m] are within ``tol`` of ``target``; raises ValueError naming the
    measurement that cannot be reached."""
    _, torch = _require()
    for k in MEASURES:
        if k not in target:
            raise ValueError(f"body measurements need {k!r} [m]; got {sorted(target)}")
    F = faces()
    y = torch.tensor([target[k] for k in MEASURES], dtype=torch.float64)
    theta = torch.tensor([0.5, 0.5, 0.0, 0.0, 0.0, 0.0], dtype=torch.float64)
    lo = torch.tensor([0.0, 0.0, -1.0, -1.0, -1.0, -1.0], dtype=torch.float64)
    hi = torch.tensor([1.0, 1.0, 1.0, 1.0, 1.0, 1.0], dtype=torch.float64)
    t0 = time.perf_counter()
    for it in range(max_iter):
        th = theta.clone().requires_grad_(True)
        m = _measures_torch(_vertices(th), F)
        r = (m - y).detach()
        if verbose:
            print(
                f"  it {it}: residual [mm] "
                + " ".join(f"{k}={1000 * v:+.1f}" for k, v in zip(MEASURES, r.tolist(), strict=True))
                + f" ({time.perf_counter() - t0:.0f} s)",
                file=sys.stderr,
            )
        if float(r.abs().max()) < tol:
            break
        J = torch.stack([torch.autograd.grad(m[i], th, retain_graph=True)[0] for i in range(len(MEASURES))])
        # damped least squares, then clip to the box
        lam = 1e-6 * float((J * J).sum())
        step = torch.linalg.solve(J.T @ J + lam * torch.eye(len(PARAMS), dtype=torch.float64), -J.T @ r)
        theta = torch.minimum(torch.maximum(theta + step, lo), hi)
    V = _vertices(theta).detach().numpy()
    measured = measure(V, F)
    bad = [k for k in MEASURES if abs(measured[k] - target[k]) > 0.01]
    if bad:
        raise ValueError(
            "Anny cannot reach "
            + ", ".join(f"{k}={target[k]:.3f} m (got {measured[k]:.3f})" for k in bad)
            + " within 1 cm with its height, weight and measurement targets"
        )
    return V, F, dict(zip(PARAMS, theta.tolist(), strict=True)), measured


def make_graded(
    out: Path = BODIES_DIR,
    names: list[str] | None = None,
    verbose: bool = True,
    table: dict[str, dict[str, float]] | None = None,
    write_sections: Callable[[Path, Path], None] | None = None,
) -> dict:
    """Fit and write every size of ``table`` (default SIZE_TABLE; or only
    ``names``): <name>.obj, the placement sections <name>.sections.npz (with
    ``write_sections(obj_path, npz_path)``, after each body), and bodies.json
    (requested vs measured, Anny parameters); copies Anny's licences beside them.

    The placement sections are the pattern's tables (about its placement axes,
    couture.pattern.sections), and couture.pattern sits above this package: the
    caller passes their writer (``couture bodies make`` passes
    couture.pattern.sections.write_body_sections)."""
    import anny

    out.mkdir(parents=True, exist_ok=True)
    index_path = out / "bodies.json"
    index = json.loads(index_path.read_text()) if index_path.exists() else {"bodies": {}}
    index["source"] = SIZE_TABLE_SOURCE
    index["generator"] = f"couture bodies make (anny {anny.__version__}, topology {TOPOLOGY!r})"
    table = SIZE_TABLE if table is None else table
    for name in names or list(table):
        if name not in table:
            raise ValueError(f"unknown size {name!r}; sizes are {list(table)}")
        if name == "default" or not name.replace("_", "").replace("-", "").isalnum():
            raise ValueError(f"body name {name!r}: use letters, digits, '-' or '_', and not 'default'")
        target = table[name]
        if verbose:
            print(f"{name}: " + ", ".join(f"{k}={v:.3f}" for k, v in target.items()), file=sys.stderr)
        V, F, params, measured = fit_body(target, verbose=verbose)
        obj = out / f"{name}.obj"
        write_obj(
            obj,
            V,
            F,
            f"couture graded body {name!r}: Anny {anny.__version__} (NAVER LABS, Apache-2.0; MakeHuman assets CC0),"
            f"\nfitted by couture.bodies.make; metres, y up, facing +z. See LICENSE and bodies.json.",
        )
        if write_sections is not None:
            write_sections(obj, out / f"{name}.sections.npz")
        index["bodies"][name] = {
            "requested": target,
            "measured": {k: round(v, 5) for k, v in measured.items()},
            "anny_parameters": {k: round(v, 6) for k, v in params.items()},
        }
        index_path.write_text(json.dumps(index, indent=2) + "\n")
    lic = Path(anny.__file__).resolve().parent.parent / f"anny-{anny.__version__}.dist-info" / "licenses" / "LICENSE"
    if lic.exists():
        shutil.copyfile(lic, out / "LICENSE")
    mp = Path(anny.__file__).resolve().parent / "data" / "mpfb2" / "LICENSE.md"
    if mp.exists():
        shutil.copyfile(mp, out / "LICENSE-MakeHuman-assets-CC0.md")
    return index
