"""Finite-difference checks for the tests: one helper for every derivative.

The habit of ipc-toolkit's tests (``python/tests/test_ipc.py``): first assert
that the analytic derivative is not trivially zero, then compare it with
central differences, O(h²), by the relative error with a floor

    |fd - an| <= rtol * max(|an|, |fd|, floor)

(max norm unless ``ord`` says otherwise; the floor keeps a derivative that is
small everywhere from asking for digits the differences do not have). A large
system is checked along a few directions (directional derivatives, one
function pair per direction) rather than column by column.

- :func:`central`: the central difference of f at x along d;
  :func:`richardson` its O(h⁴) extrapolation.
- :func:`along_axes`: the same for a row-wise f along each unit axis, every
  row at once (a batch of points).
- :func:`assert_close`: the comparison itself, with a message naming what
  failed and by how much.
- :func:`check_gradient`, :func:`check_jacobian` (:func:`check_hessian` is
  the Jacobian of a gradient): the three steps together.

Degenerate configurations to sweep a term over:
:func:`degenerate_triangles` (nearly collinear, nearly zero area, needles,
inverted, collapsed to a line) and :func:`contact_penetrations` (a vertex at
either side of the contact layer's boundary and of its stiffness ramp's end).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import numpy as np


def central(f: Callable, x, d, h: float) -> np.ndarray:
    """(f(x + h d) - f(x - h d)) / (2 h): f's derivative at x along d, O(h²)."""
    x = np.asarray(x, dtype=np.float64)
    return (np.asarray(f(x + h * d), dtype=np.float64) - np.asarray(f(x - h * d), dtype=np.float64)) / (2 * h)


def richardson(f: Callable, x, d, h: float) -> np.ndarray:
    """(4 D(h/2) - D(h)) / 3 with D the central difference (:func:`central`):
    f's derivative at x along d, O(h⁴), for a reference tighter than a
    central difference's round-off/truncation balance allows."""
    return (4.0 * central(f, x, d, h / 2) - central(f, x, d, h)) / 3.0


def along_axes(f: Callable, x, h: float) -> np.ndarray:
    """Central differences of a row-wise f (row i of f(x) depends on row i of
    x only, x (m, k)) along each unit axis of the last dimension, every row at
    once: shape f(x).shape + (k,), [..., j] the derivative along axis j."""
    x = np.asarray(x, dtype=np.float64)
    return np.stack([central(f, x, e, h) for e in np.eye(x.shape[-1])], axis=-1)


def _norm(a: np.ndarray, ord) -> float:
    a = np.asarray(a, dtype=np.float64).ravel()
    return float(np.linalg.norm(a, ord)) if a.size else 0.0


def rel_error(an, fd, floor: float = 0.0, ord=np.inf) -> float:
    """|fd - an| / max(|an|, |fd|, floor) in the norm ``ord`` (default: max)."""
    an, fd = np.asarray(an, dtype=np.float64), np.asarray(fd, dtype=np.float64)
    scale = max(_norm(an, ord), _norm(fd, ord), floor)
    return _norm(fd - an, ord) / scale if scale > 0 else 0.0


def assert_close(
    an, fd, rtol: float, *, floor: float = 0.0, nontrivial: float | None = 0.0, ord=np.inf, what=""
) -> float:
    """Assert the analytic derivative ``an`` is not trivially zero (its norm
    above ``nontrivial``; None: may be zero, where the caller checked another
    direction) and within ``rtol`` of the finite difference ``fd``
    (:func:`rel_error`); returns that relative error."""
    an, fd = np.asarray(an, dtype=np.float64), np.asarray(fd, dtype=np.float64)
    assert an.shape == fd.shape, f"{what}: analytic shape {an.shape} != finite-difference shape {fd.shape}"
    size = _norm(an, ord)
    assert np.all(np.isfinite(an)), f"{what}: the analytic derivative is not finite"
    if nontrivial is not None:
        assert size > nontrivial, (
            f"{what}: the analytic derivative is trivially zero (|an| = {size:.3g} <= {nontrivial:g})"
        )
    err = rel_error(an, fd, floor, ord)
    assert err <= rtol, (
        f"{what}: relative error {err:.3g} > {rtol:g} (|an| = {size:.3g}, |fd| = {_norm(fd, ord):.3g}, "
        f"|fd - an| = {_norm(fd - an, ord):.3g}, floor {floor:g})"
    )
    return err


def directions(shape, n: int = 3, seed: int = 0, fixed=None) -> list[np.ndarray]:
    """``n`` random normal directions of ``shape``, rows ``fixed`` (e.g. pinned vertices) zero."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        d = rng.normal(size=shape)
        if fixed is not None:
            d[fixed] = 0.0
        out.append(d)
    return out


def _dirs(x: np.ndarray, dirs, seed: int) -> Iterable[np.ndarray]:
    return directions(x.shape, dirs, seed) if isinstance(dirs, int) else [np.asarray(d, np.float64) for d in dirs]


def check_gradient(
    f: Callable,
    grad,
    x,
    *,
    h: float,
    rtol: float,
    dirs=3,
    seed: int = 0,
    floor: float = 0.0,
    nontrivial: float = 0.0,
    what="gradient",
) -> float:
    """A scalar f's gradient ``grad`` (shaped like x) at x against central
    differences along ``dirs`` (a count of random directions, or the
    directions): g·d (its size above ``nontrivial``) vs
    (f(x + h d) - f(x - h d)) / 2h. Returns the largest relative error."""
    x = np.asarray(x, dtype=np.float64)
    g = np.asarray(grad, dtype=np.float64)
    assert g.shape == x.shape, f"{what}: gradient shape {g.shape} != x shape {x.shape}"
    assert _norm(g, np.inf) > 0, f"{what}: the analytic gradient is zero"
    errs = [
        assert_close(
            np.vdot(g, d),
            central(f, x, d, h),
            rtol,
            floor=floor,
            nontrivial=nontrivial,
            what=f"{what} along direction {i}",
        )
        for i, d in enumerate(_dirs(x, dirs, seed))
    ]
    return max(errs)


def check_jacobian(
    f: Callable,
    jac,
    x,
    *,
    h: float,
    rtol: float,
    dirs=3,
    seed: int = 0,
    floor: float = 0.0,
    nontrivial: float | None = 0.0,
    ord=np.inf,
    what="Jacobian",
) -> float:
    """f's Jacobian at x against central differences along ``dirs`` (a count
    of random directions, or the directions). ``jac``: a matrix (dense or
    sparse) over x.ravel() to f(x).ravel(), or a callable d -> J d (any shape
    of f(x)'s size). Returns the largest relative error."""
    x = np.asarray(x, dtype=np.float64)
    errs = []
    for i, d in enumerate(_dirs(x, dirs, seed)):
        fd = central(f, x, d, h)
        an = jac(d) if callable(jac) else jac @ d.ravel()
        an = np.asarray(an, dtype=np.float64).reshape(fd.shape)
        errs.append(
            assert_close(an, fd, rtol, floor=floor, nontrivial=nontrivial, ord=ord, what=f"{what} along direction {i}")
        )
    return max(errs)


def check_hessian(grad: Callable, hess, x, **kw) -> float:
    """The Hessian ``hess`` (matrix or d -> H d) as the Jacobian of ``grad``
    (:func:`check_jacobian`; pass minus the forces for an energy's gradient)."""
    kw.setdefault("what", "Hessian")
    return check_jacobian(grad, hess, x, **kw)


# ---------------------------------------------------------------- degenerate configurations


def degenerate_triangles(size: float = 0.02) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """name -> (X (3, 2) rest positions [m], x (3, 3) world positions [m]) of
    one counter-clockwise triangle about ``size`` across, the cases where a
    triangle term's derivatives are hardest (ipc-toolkit sweeps its distance
    terms the same way): a regular one for reference, nearly collinear rest
    shapes (a 1e-3 sliver, a 1e-3 needle), a deformed state nearly of zero
    area (collapsed to within 1e-6 of a line), inverted (folded over in its
    plane), strongly compressed, and stretched out of plane."""
    s = size
    rot = np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])  # material (u, v) -> world (u, 0, v)
    tilt = np.array([0.0, 1.0, 0.0])

    def world(X, scale=(1.0, 1.0), lift=(0.0, 0.0, 0.0)):
        return (X * np.asarray(scale)) @ rot.T + np.outer(lift, tilt)

    regular = np.array([[0.0, 0.0], [s, 0.0], [0.4 * s, 0.9 * s]])
    sliver = np.array([[0.0, 0.0], [s, 0.0], [0.5 * s, 1e-3 * s]])
    needle = np.array([[0.0, 0.0], [s, 0.0], [s, 1e-3 * s]])
    return {
        "regular": (regular, world(regular, (1.1, 0.95), (0.0, 0.1 * s, -0.05 * s))),
        "sliver rest": (sliver, world(sliver, (1.05, 1.2), (0.0, 1e-4 * s, 0.0))),
        "needle rest": (needle, world(needle, (0.97, 1.1), (0.0, 0.0, 1e-4 * s))),
        "near-zero area state": (regular, world(regular, (1.0, 1e-6))),
        "inverted state": (regular, world(regular, (1.0, -0.8), (0.0, 0.02 * s, 0.0))),
        "compressed state": (regular, world(regular, (0.6, 0.7), (0.0, 0.05 * s, 0.1 * s))),
        "out of plane": (regular, world(regular, (1.0, 1.0), (0.0, 0.5 * s, 0.8 * s))),
    }


def contact_penetrations(ramp: float, h: float) -> np.ndarray:
    """Penetrations [m] into a contact layer whose stiffness ramps up over
    ``ramp`` [m]: just outside and just inside the layer's boundary, inside
    the ramp, either side of its end, and deep; each at least 20 h from a
    boundary (where the law is only C²: a central difference of step h must
    not straddle it)."""
    d = 20 * h
    return np.array([-d, d, 0.5 * ramp, ramp - d, ramp + d, 3 * ramp])
