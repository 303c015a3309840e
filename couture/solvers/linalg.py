"""Sparse linear algebra shared by the solvers: the reduced (free-DOF, seam-first)
system, an IC(0)-preconditioned CG, and swappable direct Cholesky/LU backends.

Direct backends (``factorize(A, backend=...)``), best first under ``'auto'``:

- ``'cholmod'``  scikit-sparse CHOLMOD (supernodal Cholesky, symbolic analysis
  reused across refactorizations). Optional extra ``couture[fast]``; needs the
  SuiteSparse headers to build (``apt-get install libsuitesparse-dev``).
- ``'pardiso'``  pypardiso (MKL PARDISO). Optional; a pip wheel, but MKL is a
  ~220 MB download.
- ``'splu'``     scipy SuperLU, always available (the CI fallback).

``available_backends()`` lists what imports here.
"""

from __future__ import annotations

import os
import time

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
        self.A_map = (S.data.astype(np.int64) - 1)
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
        it, rr = kernels.pcg_ic0(system.Ap, system.Ai, system.Ax, system.Lp, system.Li, np.zeros(1), ds, b, x, rtol, maxiter, False)
    else:
        it, rr = kernels.pcg_ic0(system.Ap, system.Ai, system.Ax, system.Lp, system.Li, pre.Lx, pre.dscale, b, x, rtol, maxiter, True)
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
        out.append("pardiso")
    if _have("sksparse.cholmod"):
        out.append("cholmod")
    out.append("splu")
    return out


class Factor:
    """A factorization of a symmetric matrix; ``solve(b)``, ``refactor(A)``, ``backend``."""

    backend = "?"

    def solve(self, b: np.ndarray) -> np.ndarray:  # pragma: no cover - interface
        raise NotImplementedError

    def refactor(self, A: sp.csr_matrix) -> None:  # pragma: no cover - interface
        raise NotImplementedError


class _SpluFactor(Factor):
    backend = "splu"

    def __init__(self, A):
        self.refactor(A)

    def refactor(self, A):
        try:
            self._lu = spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                 options={"SymmetricMode": True})
        except RuntimeError as e:  # exactly singular
            raise FactorizationError(str(e)) from e
        # SuperLU is an LU: a non-positive pivot means A is not SPD (needed for descent directions)
        d = self._lu.U.diagonal()
        if not np.all(np.isfinite(d)) or np.any(d <= 0):
            raise FactorizationError("matrix not positive definite (non-positive LU pivot)")

    def solve(self, b):
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

    def refactor(self, A):
        from sksparse.cholmod import CholmodNotPositiveDefiniteError

        A = sp.csc_matrix(A)
        A.sort_indices()
        if self._pattern is None or self._pattern[0].shape != A.indptr.shape or not (
                np.array_equal(self._pattern[0], A.indptr) and np.array_equal(self._pattern[1], A.indices)):
            self._analyze(A)
        try:
            self._f.cholesky_inplace(A)
        except CholmodNotPositiveDefiniteError as e:
            raise FactorizationError(str(e)) from e

    def solve(self, b):
        return self._f(b)


_PARDISO_FN = None


class _PardisoFactor(Factor):
    """MKL PARDISO through pypardiso's library loader, called directly so the
    symbolic phase (METIS ordering, 11) runs once per sparsity pattern and a
    refactorization is only the numeric phase (22): on the 10k-vertex skirt
    (31k DOF, 1.15M nonzeros) 0.12 s instead of 0.23 s for pypardiso's
    analyse-and-factor (measured, bench/results/solver.json)."""

    backend = "pardiso"
    _ERRORS = {-1: "input inconsistent", -2: "not enough memory", -3: "reordering problem",
               -4: "zero or negative pivot: matrix not positive definite", -5: "unclassified internal error",
               -6: "reordering failed", -7: "diagonal matrix is singular", -8: "32-bit integer overflow",
               -9: "not enough memory for out-of-core", -10: "problems opening out-of-core files",
               -11: "read/write problems with out-of-core data", -12: "wrong pardiso_64 call"}

    def __init__(self, A):
        import ctypes

        import pypardiso

        global _PARDISO_FN
        self._ct = ctypes
        if _PARDISO_FN is None:  # pypardiso finds mkl_rt (a glob over the venv: ~0.1 s) and sets argtypes
            _PARDISO_FN = pypardiso.PyPardisoSolver(mtype=2)._mkl_pardiso
        self._fn = _PARDISO_FN
        self._pt = np.zeros(64, dtype=np.int64)
        self._iparm = np.zeros(64, dtype=np.int32)
        self._iparm[0] = 1  # explicit parameters below, otherwise defaults
        self._iparm[1] = 2  # METIS nested dissection
        self._iparm[9] = 8  # pivot perturbation 1e-8 (only used for indefinite types)
        self._iparm[34] = 1  # zero-based ia/ja
        self._perm = np.zeros(1, dtype=np.int32)
        self._pattern = None
        self._n = 0
        self.refactor(A)

    def _call(self, phase: int, data: np.ndarray, b: np.ndarray | None = None) -> np.ndarray | None:
        ct = self._ct
        i32 = ct.POINTER(ct.c_int32)
        f64 = ct.POINTER(ct.c_double)
        nrhs = 1 if b is None or b.ndim == 1 else b.shape[1]
        bb = np.zeros(1) if b is None else np.asfortranarray(b, dtype=np.float64)
        x = np.zeros_like(bb)
        err = ct.c_int32(0)
        self._fn(self._pt.ctypes.data_as(ct.POINTER(ct.c_int64)), ct.byref(ct.c_int32(1)), ct.byref(ct.c_int32(1)),
                 ct.byref(ct.c_int32(2)), ct.byref(ct.c_int32(phase)), ct.byref(ct.c_int32(self._n)),
                 data.ctypes.data_as(f64), self._ia.ctypes.data_as(i32), self._ja.ctypes.data_as(i32),
                 self._perm.ctypes.data_as(i32), ct.byref(ct.c_int32(nrhs)), self._iparm.ctypes.data_as(i32),
                 ct.byref(ct.c_int32(0)), bb.ctypes.data_as(f64), x.ctypes.data_as(f64), ct.byref(err))
        if err.value != 0:
            raise FactorizationError(f"PARDISO phase {phase}: error {err.value} "
                                     f"({self._ERRORS.get(err.value, 'unknown')})")
        return None if b is None else np.ascontiguousarray(x)

    def refactor(self, A):
        A = sp.csr_matrix(A)
        if self._pattern is None or self._pattern[0].shape != A.indptr.shape or not (
                np.array_equal(self._pattern[0], A.indptr) and np.array_equal(self._pattern[1], A.indices)):
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
            self._data = np.ascontiguousarray(A.data[self._up], dtype=np.float64)
            self._call(11, self._data)
        else:
            self._data = np.ascontiguousarray(A.data[self._up], dtype=np.float64)
        if not np.all(np.isfinite(self._data)):
            raise FactorizationError("matrix has non-finite entries")
        self._call(22, self._data)

    def solve(self, b):
        x = self._call(33, self._data, np.asarray(b, dtype=np.float64))
        if not np.all(np.isfinite(x)):
            raise FactorizationError("PARDISO produced a non-finite solution")
        return x

    def __del__(self):
        try:
            if self._pattern is not None:
                self._call(-1, np.zeros(1))
        except Exception:
            pass


_BACKENDS = {"splu": _SpluFactor, "cholmod": _CholmodFactor, "pardiso": _PardisoFactor}


def resolve_backend(backend: str = "auto") -> str:
    if backend == "auto":
        return available_backends()[0]
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


def pcg_factor(A: sp.csr_matrix, b: np.ndarray, x0: np.ndarray | None, factor: "Factor", rtol: float,
               maxiter: int) -> tuple[np.ndarray, int, float]:
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
    z = factor.solve(r)
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
        z = factor.solve(r)
        rz_new = float(r @ z)
        p *= rz_new / rz
        p += z
        rz = rz_new
    return x, it, rn / bn
