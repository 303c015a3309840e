"""Sparse linear algebra shared by the solvers: the reduced (free-DOF, seam-first)
system, an IC(0)-preconditioned CG, and swappable direct Cholesky/LU backends.

Direct backends (``factorize(A, backend=...)``), best first under ``'auto'``:

- ``'pardiso'``   MKL PARDISO in double precision. Optional extra
  ``couture[fast]`` (pypardiso, a pip wheel that brings MKL, ~700 MB installed).
- ``'pardiso32'`` the same in single precision, refined in double: conjugate
  gradients preconditioned by the single factor, to the relative residual the
  caller asks (``solve(b, rtol)``, default 1e-10). On fine-skirt Newton
  matrices (31k DOF) the numeric factorization takes 50-90 ms instead of
  100-150 ms; a solve to 1e-3 takes 2 refinement steps, to 1e-10 about 9
  (~12 ms each). A matrix too ill-conditioned for single precision (a
  negative pivot, or no convergence in 20 steps) switches that factor to
  double for good. Those figures are from an older MKL: under MKL 2026.2
  the same matrix factorizes in 595-704 ms single against 76-134 ms double,
  so 'auto' no longer picks it; it stays available by name.
- ``'cholmod'``   scikit-sparse CHOLMOD (supernodal Cholesky, symbolic analysis
  reused across refactorizations). Needs the SuiteSparse headers to build;
  Debian's links the reference BLAS here, so it is slower than PARDISO.
- ``'splu'``      scipy SuperLU, always available (the fallback).

``available_backends()`` lists what imports here.
"""

from __future__ import annotations

import os
import time
from typing import overload

# MKL's conditional numerical reproducibility: PARDISO's threaded factorization
# otherwise differs in the last bits from run to run (measured: 1 of 8 solves),
# and recordings replayed as regression tests need identical solves. AUTO keeps
# the CPU's fast code path (run to run on one machine; COMPATIBLE would be the
# same on every CPU but measured 1.8x slower). Read when MKL loads, so set here.
os.environ.setdefault("MKL_CBWR", "AUTO")

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from . import kernels


class FactorizationError(RuntimeError):
    """The matrix is not (numerically) positive definite for a Cholesky backend, or singular."""


# --------------------------------------------------------------------------
# reduced system: pinned DOFs removed, SC seam-first ordering
# --------------------------------------------------------------------------


def seam_first_order(n: int, free: np.ndarray, emitters=(), receivers=()) -> np.ndarray:
    """Vertex order for the reduced system: seam emitters, then receivers, then the
    rest (SC §7: ILU/IC favour large entries top-left). Pinned vertices dropped."""
    rank = np.full(n, 2, np.int64)
    if len(receivers):
        rank[np.asarray(receivers).ravel()] = 1
    if len(emitters):
        rank[np.asarray(emitters)] = 0
    order = np.lexsort((np.arange(n), rank))
    return order[free[order]]


class ReducedSystem:
    """Maps a model's stiffness K (3n x 3n CSR, fixed pattern) to the reduced,
    permuted SPD system ``A = c_M * diag(m) + c_K * K`` on free DOFs.

    The index maps are built once from the pattern (values carried through
    scipy's structural operations as 1-based positions); each call then only
    gathers K.data, so forming A costs a memory copy, not a sparse slice.
    """

    def __init__(self, K: sp.csr_matrix, mass: np.ndarray, free: np.ndarray, vertex_order: np.ndarray):
        K = sp.csr_matrix(K)
        K.sort_indices()
        self.nnz_K = K.nnz
        self._K_indices = K.indices.copy()
        dof = (3 * vertex_order[:, None] + np.arange(3)[None, :]).ravel()
        self.dof = dof  # reduced index -> full DOF
        self.nr = len(dof)
        T = sp.csr_matrix((np.arange(1, K.nnz + 1, dtype=np.float64), K.indices, K.indptr), shape=K.shape)
        S = T[dof][:, dof].tocsr()
        S.sort_indices()
        self.Ap = S.indptr.astype(np.int64)
        self.Ai = S.indices.astype(np.int64)
        self.A_map = S.data.astype(np.int64) - 1
        rows = np.repeat(np.arange(self.nr), np.diff(S.indptr))
        diag_pos = np.nonzero(S.indices == rows)[0]
        if len(diag_pos) != self.nr:
            raise ValueError("stiffness pattern lacks diagonal entries")
        self.diag_pos = diag_pos
        self.m_red = np.repeat(mass[vertex_order], 3)
        low = rows >= S.indices
        self.low_pos = np.nonzero(low)[0]
        Lcount = np.bincount(rows[low], minlength=self.nr)
        self.Lp = np.concatenate([[0], np.cumsum(Lcount)]).astype(np.int64)
        self.Li = S.indices[low].astype(np.int64)
        self.Ax = np.zeros(len(self.A_map))

    def same_pattern(self, K: sp.csr_matrix) -> bool:
        return K.nnz == self.nnz_K and np.array_equal(K.indices, self._K_indices)

    def assemble(self, K: sp.csr_matrix, c_K: float, c_M: float) -> np.ndarray:
        kernels.gather_add(self.Ax, K.data, self.A_map, c_K)
        if c_M:
            self.Ax[self.diag_pos] += c_M * self.m_red
        return self.Ax

    def matrix(self) -> sp.csr_matrix:
        return sp.csr_matrix((self.Ax.copy(), self.Ai, self.Ap), shape=(self.nr, self.nr))

    def restrict(self, v_full: np.ndarray) -> np.ndarray:
        return v_full.ravel()[self.dof]

    def prolong(self, v_red: np.ndarray, n: int) -> np.ndarray:
        out = np.zeros(3 * n)
        out[self.dof] = v_red
        return out.reshape(n, 3)


class IC0:
    """Shifted incomplete Cholesky IC(0) of the Jacobi-scaled matrix.

    The shift starts at ``shift0`` and grows ×10 on breakdown (Manteuffel's
    shifted IC); it is kept for later refactorizations and relaxed again when
    a factorization succeeds first time, so a sequence of similar matrices
    pays for at most a few retries.
    """

    def __init__(self, system: ReducedSystem, shift0: float = 1e-3):
        self.sys = system
        self.shift = shift0
        self.shift0 = shift0
        self.Lx = np.zeros(len(system.Li))
        self.dscale = np.ones(system.nr)
        self.retries = 0

    def factor(self, Ax: np.ndarray) -> None:
        s = self.sys
        d = Ax[s.diag_pos]
        if not np.all(d > 0):
            d = np.where(d > 0, d, np.max(np.abs(d)) + 1e-300)
        self.dscale = 1.0 / np.sqrt(d)
        Alow = Ax[s.low_pos]
        first = True
        while True:
            bad = kernels.ic0_factor(s.Lp, s.Li, Alow, self.dscale, self.shift, self.Lx)
            if bad < 0:
                break
            self.retries += 1
            first = False
            self.shift = 1.0 if self.shift <= 0 else self.shift * 10.0
            if self.shift > 1e3:
                raise FactorizationError("IC(0) breaks down even with a large shift")
        if first and self.shift > self.shift0:
            self.shift = max(self.shift0, self.shift / 10.0)


def pcg(system: ReducedSystem, b: np.ndarray, x0: np.ndarray | None, pre: IC0 | None, rtol: float, maxiter: int):
    """CG on the reduced system's current A with IC(0) (``pre``) or Jacobi. Returns (x, iters, relres)."""
    x = np.zeros(system.nr) if x0 is None else np.array(x0, dtype=np.float64, copy=True)
    if pre is None:
        d = system.Ax[system.diag_pos]
        ds = 1.0 / np.sqrt(np.where(d > 0, d, 1.0))
        it, rr = kernels.pcg_ic0(
            system.Ap, system.Ai, system.Ax, system.Lp, system.Li, np.zeros(1), ds, b, x, rtol, maxiter, False
        )
    else:
        it, rr = kernels.pcg_ic0(
            system.Ap, system.Ai, system.Ax, system.Lp, system.Li, pre.Lx, pre.dscale, b, x, rtol, maxiter, True
        )
    return x, int(it), float(rr)


# --------------------------------------------------------------------------
# direct backends
# --------------------------------------------------------------------------


def _have(mod: str) -> bool:
    try:
        __import__(mod)
        return True
    except Exception:
        return False


def available_backends() -> list[str]:
    out = []
    if _have("pypardiso"):
        out += ["pardiso", "pardiso32"]
    if _have("sksparse.cholmod"):
        out.append("cholmod")
    out.append("splu")
    return out


class Factor:
    """A factorization of a symmetric matrix; ``solve(b)``, ``refactor(A)``, ``backend``."""

    backend = "?"

    def solve(self, b: np.ndarray, rtol: float | None = None) -> np.ndarray:  # pragma: no cover - interface
        """A⁻¹ b; ``rtol``: the relative residual the caller needs (backends that
        refine an approximate factorization stop there, ``rtol >= 1`` skips the
        refinement, as for a preconditioner; exact backends ignore it)."""
        raise NotImplementedError

    def refactor(self, A: sp.csr_matrix, *, expect_indefinite: bool = False) -> None:  # pragma: no cover - interface
        raise NotImplementedError


class _SpluFactor(Factor):
    backend = "splu"

    def __init__(self, A):
        self.refactor(A)

    def refactor(self, A, *, expect_indefinite: bool = False):
        try:
            self._lu = spla.splu(
                sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True}
            )
        except RuntimeError as e:  # exactly singular
            raise FactorizationError(str(e)) from e
        # SuperLU is an LU: a non-positive pivot means A is not SPD (needed for descent directions)
        d = self._lu.U.diagonal()
        if not np.all(np.isfinite(d)) or np.any(d <= 0):
            raise FactorizationError("matrix not positive definite (non-positive LU pivot)")

    def solve(self, b, rtol=None):
        return self._lu.solve(b)


class _CholmodFactor(Factor):
    backend = "cholmod"

    def __init__(self, A):
        self._pattern = None
        self.refactor(A)

    def _analyze(self, A):
        from sksparse.cholmod import analyze

        # nested dissection (METIS) fills in ~10% less than AMD on garment meshes
        # and factors 1.5-3x faster (measured, 1.6k and 10k-vertex skirts)
        try:
            self._f = analyze(A, mode="supernodal", ordering_method="nesdis")
        except Exception:  # CHOLMOD built without METIS
            self._f = analyze(A, mode="supernodal", ordering_method="amd")
        self._pattern = (A.indptr.copy(), A.indices.copy())

    def refactor(self, A, *, expect_indefinite: bool = False):
        from sksparse.cholmod import CholmodNotPositiveDefiniteError

        A = sp.csc_matrix(A)
        A.sort_indices()
        if (
            self._pattern is None
            or self._pattern[0].shape != A.indptr.shape
            or not (np.array_equal(self._pattern[0], A.indptr) and np.array_equal(self._pattern[1], A.indices))
        ):
            self._analyze(A)
        try:
            self._f.cholesky_inplace(A)
        except CholmodNotPositiveDefiniteError as e:
            raise FactorizationError(str(e)) from e

    def solve(self, b, rtol=None):
        return self._f(b)


_PARDISO_FN = None


def _pardiso_fn():
    """MKL's ``pardiso`` with pypardiso's argument types, loaded once a process.

    pypardiso looks for mkl_rt with ``find_library`` and then a recursive glob
    over ``sys.prefix/lib*``, the whole environment: 0.2 s a process on an
    idle machine (0.6 s loaded), paid by every solver and sensitivity node at
    its first factorization. Its wheel puts mkl_rt in ``sys.prefix/lib``:
    looked for there first, and handed to pypardiso through its
    ``PYPARDISO_MKL_RT`` for the construction only."""
    global _PARDISO_FN
    if _PARDISO_FN is None:
        import glob
        import sys

        import pypardiso

        key = "PYPARDISO_MKL_RT"
        found = [] if key in os.environ else sorted(glob.glob(os.path.join(sys.prefix, "lib", "*mkl_rt*")), key=len)
        if found:
            os.environ[key] = found[0]
        try:
            _PARDISO_FN = pypardiso.PyPardisoSolver(mtype=2)._mkl_pardiso
        finally:
            if found:
                del os.environ[key]
    return _PARDISO_FN


class _PardisoFactor(Factor):
    """MKL PARDISO through pypardiso's library loader, called directly so the
    symbolic phase (METIS ordering, 11) runs once per sparsity pattern and a
    refactorization is only the numeric phase (22): on the 10k-vertex skirt
    (31k DOF, 1.15M nonzeros) 0.12 s instead of 0.23 s for pypardiso's
    analyse-and-factor (measured, bench/results/solver.json)."""

    backend = "pardiso"
    _ERRORS = {
        -1: "input inconsistent",
        -2: "not enough memory",
        -3: "reordering problem",
        -4: "zero or negative pivot: matrix not positive definite",
        -5: "unclassified internal error",
        -6: "reordering failed",
        -7: "diagonal matrix is singular",
        -8: "32-bit integer overflow",
        -9: "not enough memory for out-of-core",
        -10: "problems opening out-of-core files",
        -11: "read/write problems with out-of-core data",
        -12: "wrong pardiso_64 call",
    }

    single = False
    refine_rtol = 1e-10
    max_refine = 20

    def __init__(self, A):
        import ctypes

        self._ct = ctypes
        self._fn = _pardiso_fn()
        self._pt = np.zeros(64, dtype=np.int64)
        self._iparm = np.zeros(64, dtype=np.int32)
        self._iparm[0] = 1  # explicit parameters below, otherwise defaults
        self._iparm[1] = 2  # METIS nested dissection
        self._iparm[9] = 8  # pivot perturbation 1e-8 (only used for indefinite types)
        self._iparm[34] = 1  # zero-based ia/ja
        self._iparm[27] = int(self.single)  # single-precision factorization
        self.refinements = 0  # refinement steps of the last solve (single precision)
        self.double_fallback = False  # refinement stalled once: factorizing in double since
        self._perm = np.zeros(1, dtype=np.int32)
        self._pattern = None
        self._n = 0
        self.refactor(A)

    @overload
    def _call(self, phase: int, data: np.ndarray) -> None: ...

    @overload
    def _call(self, phase: int, data: np.ndarray, b: np.ndarray) -> np.ndarray: ...

    def _call(self, phase: int, data: np.ndarray, b: np.ndarray | None = None) -> np.ndarray | None:
        """One PARDISO phase; with a right-hand side b, the solution."""
        ct = self._ct
        i32 = ct.POINTER(ct.c_int32)
        f64 = ct.POINTER(ct.c_double)
        nrhs = 1 if b is None or b.ndim == 1 else b.shape[1]
        dt = np.float32 if self._iparm[27] else np.float64
        bb = np.zeros(1, dt) if b is None else np.asfortranarray(b, dtype=dt)
        x = np.zeros_like(bb)
        err = ct.c_int32(0)
        self._fn(
            self._pt.ctypes.data_as(ct.POINTER(ct.c_int64)),
            ct.byref(ct.c_int32(1)),
            ct.byref(ct.c_int32(1)),
            ct.byref(ct.c_int32(2)),
            ct.byref(ct.c_int32(phase)),
            ct.byref(ct.c_int32(self._n)),
            data.ctypes.data_as(f64),
            self._ia.ctypes.data_as(i32),
            self._ja.ctypes.data_as(i32),
            self._perm.ctypes.data_as(i32),
            ct.byref(ct.c_int32(nrhs)),
            self._iparm.ctypes.data_as(i32),
            ct.byref(ct.c_int32(0)),
            bb.ctypes.data_as(f64),
            x.ctypes.data_as(f64),
            ct.byref(err),
        )
        if err.value != 0:
            raise FactorizationError(
                f"PARDISO phase {phase}: error {err.value} ({self._ERRORS.get(err.value, 'unknown')})"
            )
        return None if b is None else np.ascontiguousarray(x)

    def refactor(self, A, *, expect_indefinite: bool = False):
        """Numeric factorization of A (symbolic analysis only for a new pattern). A
        negative pivot in single precision is retried in double, for good on this
        object, unless ``expect_indefinite`` (the caller tries a matrix that may well be
        indefinite, e.g. a shifted true Hessian): then it raises at once and the
        object stays usable for the next matrix."""
        A = sp.csr_matrix(A)
        if (
            self._pattern is None
            or self._pattern[0].shape != A.indptr.shape
            or not (np.array_equal(self._pattern[0], A.indptr) and np.array_equal(self._pattern[1], A.indices))
        ):
            A.sort_indices()
            rows = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
            up = A.indices >= rows
            self._up = np.nonzero(up)[0]
            self._ia = np.concatenate([[0], np.cumsum(np.bincount(rows[up], minlength=A.shape[0]))]).astype(np.int32)
            self._ja = A.indices[up].astype(np.int32)
            if self._pattern is not None:
                self._call(-1, np.zeros(1))  # release the old pattern's memory
                self._pt[:] = 0
            self._n = A.shape[0]
            self._pattern = (A.indptr.copy(), A.indices.copy())
            self._data = self._values(A)
            self._call(11, self._data)
        else:
            self._data = self._values(A)
        if not np.all(np.isfinite(self._data)):
            raise FactorizationError("matrix has non-finite entries")
        self._A = A
        try:
            self._call(22, self._data)
        except FactorizationError:
            if not self._iparm[27] or expect_indefinite:
                raise
            # a negative pivot in single precision can be round-off on an SPD but
            # ill-conditioned matrix: decide in double
            self._to_double()
            self._call(22, self._data)

    def _values(self, A):
        return np.ascontiguousarray(A.data[self._up], dtype=np.float32 if self._iparm[27] else np.float64)

    def solve(self, b, rtol: float | None = None):
        """A⁻¹ b; single precision refines to a relative residual ``rtol``
        (default ``refine_rtol``, 1e-10; Newton asks less far from equilibrium;
        ``rtol >= 1``: the single solve as it is, for a preconditioner)."""
        b = np.asarray(b, dtype=np.float64)
        x = self._call(33, self._data, b).astype(np.float64)
        if self._iparm[27] and (rtol is None or rtol < 1.0):
            x = self._refine(b, x, self.refine_rtol if rtol is None else max(rtol, self.refine_rtol))
        if not np.all(np.isfinite(x)):
            raise FactorizationError("PARDISO produced a non-finite solution")
        return x

    def _refine(self, b, x, rtol):
        """Refine a single-precision solve x of A x = b: conjugate gradients on A
        (residuals in double) preconditioned by the single factor, until
        ||b - A x|| <= rtol ||b||. Measured on a fine-skirt Newton matrix
        (31k DOF, diagonal 0.27..3.9e4): the single solve alone leaves 2.6e-2,
        CG reaches 1e-3 in 2 steps, 1e-6 in 6, 1e-10 in 9 (plain iterative
        refinement: 1e-6 after 7). No convergence within ``max_refine`` steps
        (a matrix too ill-conditioned for single precision) refactors in double
        precision, for good on this factor object."""
        x, self.refinements, rr = pcg_factor(self._A, b, x, self, rtol, self.max_refine)
        if rr <= rtol and np.all(np.isfinite(x)):
            return x
        # not converged: double precision from now on
        self._to_double()
        self._call(22, self._data)
        return self._call(33, self._data, b)

    def _to_double(self):
        """Switch this factor to double precision for good (new symbolic phase)."""
        self._call(-1, np.zeros(1))
        self._pt[:] = 0
        self._iparm[27] = 0
        self.double_fallback = True
        self._data = self._values(self._A)
        self._call(11, self._data)

    def __del__(self):
        try:
            if self._pattern is not None:
                self._call(-1, np.zeros(1))
        except Exception:  # noqa: BLE001 - at interpreter exit MKL or ctypes may be gone: nothing to release then
            pass


class _Pardiso32Factor(_PardisoFactor):
    """Single-precision PARDISO factorization with double-precision iterative
    refinement (``_PardisoFactor._refine``)."""

    backend = "pardiso32"
    single = True


_BACKENDS = {"splu": _SpluFactor, "cholmod": _CholmodFactor, "pardiso": _PardisoFactor, "pardiso32": _Pardiso32Factor}


def resolve_backend(backend: str = "auto", approximate: bool = False) -> str:
    """'auto': the fastest exact backend available, approximate or not.

    The single-precision PARDISO ('pardiso32', by name only) was picked for
    callers that pass a tolerance until MKL 2026.2: there its numeric
    factorization of the fine skirt's Newton matrix (31k DOF, 1.15M nonzeros)
    takes 595-704 ms against 76-134 ms in double (1 and 2 threads), and the
    fine level's iterations cost 465 ms instead of 213 ms."""
    del approximate  # kept for callers that still say so
    if backend == "auto":
        return next(b for b in available_backends() if b != "pardiso32")
    if backend not in _BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose from {sorted(_BACKENDS)} or 'auto'")
    return backend


def factorize(A: sp.spmatrix, backend: str = "auto") -> Factor:
    """Factor a symmetric positive definite A; raises FactorizationError when it is not."""
    return _BACKENDS[resolve_backend(backend)](A)


def time_backends(A: sp.spmatrix, repeats: int = 2) -> dict[str, dict[str, float]]:
    """First factorization and refactorization wall times [s] of every available backend."""
    out = {}
    for name in available_backends():
        t0 = time.perf_counter()
        f = factorize(A, name)
        t1 = time.perf_counter()
        best = np.inf
        for _ in range(repeats):
            t = time.perf_counter()
            f.refactor(A)
            best = min(best, time.perf_counter() - t)
        t = time.perf_counter()
        f.solve(np.ones(A.shape[0]))
        out[name] = {"first_s": t1 - t0, "refactor_s": best, "solve_s": time.perf_counter() - t}
    return out


def pcg_factor(
    A: sp.csr_matrix, b: np.ndarray, x0: np.ndarray | None, factor: "Factor", rtol: float, maxiter: int
) -> tuple[np.ndarray, int, float]:
    """CG on SPD ``A`` preconditioned by a direct factorization of a nearby matrix
    (an earlier step's ``M + dt² K``): exact for the matrix it was made from, so
    CG needs a handful of iterations while K drifts, and the expensive
    factorization is amortized over many steps. Returns (x, iterations, ||r||/||b||)."""
    x = np.zeros(len(b)) if x0 is None else np.array(x0, dtype=np.float64, copy=True)
    bn = float(np.linalg.norm(b))
    if bn == 0.0:
        return np.zeros(len(b)), 0, 0.0
    r = b - A @ x
    rn = float(np.linalg.norm(r))
    if rn <= rtol * bn:
        return x, 0, rn / bn
    z = factor.solve(r, rtol=1.0)
    p = z.copy()
    rz = float(r @ z)
    it = 0
    while it < maxiter:
        it += 1
        q = A @ p
        pq = float(p @ q)
        if not pq > 0.0:
            break
        alpha = rz / pq
        x += alpha * p
        r -= alpha * q
        rn = float(np.linalg.norm(r))
        if rn <= rtol * bn or not np.isfinite(rn):
            break
        z = factor.solve(r, rtol=1.0)
        rz_new = float(r @ z)
        p *= rz_new / rz
        p += z
        rz = rz_new
    return x, it, rn / bn
