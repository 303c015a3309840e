"""A factorization of the equilibrium stiffness, kept ready for sensitivity solves.

SC §4: at an equilibrium x of R(X, x) = F - Q = 0 the design sensitivity is
``dx = -(∂R/∂x)⁻¹ (∂R/∂X) dX``. With ``model.forces(x) = -dE/dx`` we have
``∂R/∂x = -K`` (K = ``model.stiffness(x)``, PSD), hence

    dx = K⁻¹ · model.dforces_dX(x, dX)            (pinned DOFs: dx = 0)

K is the model's own exact Hessian with every term the solver converged,
friction included: anchors as the springs they are, slipping vertices as a
constant force (set the model's friction state first, e.g. with
:func:`couture.sensitivity.friction.hold_friction`).

Safeguards, each reported in :class:`FactorInfo` (``info.regularization``):

- **Regularization only where needed** (SC §7): by default (``bend_floor=False``)
  the exact linearisation is factored as it is, and a thicker bending or a
  shift is added only when that factorization fails or is near-singular (next
  item). Its effect on the prediction is measured: ``info.regularization_effect``
  is the relative residual ``||K s - b|| / ||b||`` of the regularized solution
  in the unregularized system, for the latest columns (0 without regularization).
- **Bending floor** (SC implementation fact, opt-in with ``bend_floor=True``):
  the solve then always uses a bending stiffness of at least
  ``k_floor = 1e-4 (λ + μ) L²`` (h = 1/100 relative thickness, L the
  bounding-box diagonal of the pattern), by adding ``(k_floor - k_b)⁺ Q`` with Q
  the constant isometric-bending Hessian. On light fabrics that is thousands
  of times their bending: measured on a sheet over a sphere it moves the
  derivative by ~10 % (0.09 % without), so it is not the default.
- **Near-singular fallback** (SC §7 "Full-rank of sensitivity matrix"): after
  factoring, a few steps of inverse iteration estimate the smallest eigenvalue;
  if it is below ``singular_tol`` times the median diagonal (or the
  factorization breaks down), the matrix is refactored with the thick bending
  (the floor when it was off, else 100× it, and as a last resort a small
  diagonal shift).
- **Exact free modes**: rigid motions that K annihilates (a garment on a
  frictionless body of revolution can spin about its axis) are found among the
  six rigid modes by an SVD of ``K B`` and projected out: the right-hand side is
  projected onto their orthogonal complement, one gauge DOF per mode is pinned,
  and the solution is projected again, so a response never contains a spurious
  spin.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from couture.cloth.model import ClothModel

from .bending import length_scale, model_bending, model_lame
from .dfdx import DForcesDX

if TYPE_CHECKING:  # the type checker sees the solvers' names; at run time they may be missing
    from couture.solvers.linalg import FactorizationError
    from couture.solvers.linalg import available_backends as _available_backends
    from couture.solvers.linalg import factorize as _solvers_factorize
else:
    try:  # the solvers' direct backends (CHOLMOD/PARDISO when installed, SuperLU always)
        from couture.solvers.linalg import FactorizationError
        from couture.solvers.linalg import available_backends as _available_backends
        from couture.solvers.linalg import factorize as _solvers_factorize
    except Exception:  # pragma: no cover - solvers package not importable

        class FactorizationError(RuntimeError):
            pass

        _solvers_factorize = None


class _SpluFactor:
    backend = "splu"

    def __init__(self, A):
        try:
            self._lu = spla.splu(
                sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True}
            )
        except RuntimeError as e:
            raise FactorizationError(str(e)) from e
        d = self._lu.U.diagonal()
        if not np.all(np.isfinite(d)) or np.any(d <= 0):
            raise FactorizationError("matrix not positive definite (non-positive LU pivot)")

    def solve(self, b):
        return self._lu.solve(b)


class _CholmodCached:
    """CHOLMOD LLᵀ (supernodal, nested-dissection ordering) with the symbolic
    analysis reused while the sparsity pattern stays the same: the equilibria
    of one mesh share the stiffness pattern, so a refactorization at a new
    sample is numeric only. Supernodal + nested dissection factors garment-size
    stiffnesses faster than simplicial + AMD (``couture bench sensitivity``)."""

    backend = "cholmod"
    mode, ordering = "supernodal", "nesdis"
    _symbolic: dict = {}

    def __init__(self, A):
        from sksparse.cholmod import CholmodNotPositiveDefiniteError, analyze

        A = sp.csc_matrix(A)
        A.sort_indices()
        key = (A.shape, A.nnz, hash(A.indptr.tobytes()), hash(A.indices.tobytes()))
        sym = self._symbolic.get(key)
        if sym is None:
            sym = analyze(A, mode=self.mode, ordering_method=self.ordering)
            if len(self._symbolic) >= 4:
                self._symbolic.clear()
            self._symbolic[key] = sym
        try:
            self._f = sym.cholesky(A)  # a new numeric factor on the shared analysis
        except CholmodNotPositiveDefiniteError as e:
            raise FactorizationError(str(e)) from e

    def solve(self, b):
        return self._f(b)


def _factorize(A, backend: str = "auto"):
    """SPD factorization with ``solve(b)``; raises FactorizationError when A is not SPD.

    'auto': MKL PARDISO when installed (couture[fast]; the faster at fine-mesh
    size, see bench/results/sensitivity.json), else CHOLMOD (symbolic
    analysis shared), else SuperLU."""
    if backend == "auto" and _solvers_factorize is not None and "pardiso" in _available_backends():
        return _solvers_factorize(A, "pardiso")
    if backend in ("auto", "cholmod"):
        try:
            import sksparse.cholmod  # noqa: F401

            return _CholmodCached(A)
        except ImportError:
            if backend != "auto":
                raise
    if backend == "splu" or _solvers_factorize is None:
        return _SpluFactor(A)
    return _solvers_factorize(A, "auto" if backend == "auto" else backend)


@dataclass
class FactorInfo:
    """What a factorization did, for logs, messages and the benchmark."""

    refactor_s: float = 0.0
    """wall time of the whole refactorization (assembly, factor, checks) [s]"""
    factor_s: float = 0.0
    """wall time of the numeric factorization(s) alone [s]"""
    backend: str = ""
    n_dofs: int = 0
    bend_stiffness: float = 0.0
    """the model's bending stiffness k_b [N m]"""
    bend_floor: float = 0.0
    """k_floor = 1e-4 (λ + μ) L² [N m]"""
    bend_added: float = 0.0
    """bending stiffness added for the sensitivity solve [N m]"""
    shift: float = 0.0
    """diagonal shift added as a last resort [N/m] (0 normally)"""
    lambda_min_rel: float = float("nan")
    """estimated smallest eigenvalue / median diagonal of the factored matrix"""
    null_modes: int = 0
    """number of exact rigid free modes projected out"""
    fallback: str = ""
    """empty normally; otherwise why and how the matrix was thickened"""
    fast_dforces_dX: bool = True
    """presses use the model's matrix-free bending derivative (always, since the
    model has only that one; the field stays for the benchmark's report)"""
    exact_hessian: bool = True
    """True when the unprojected membrane Hessian was factored (exact linearisation)"""
    attempts: list = field(default_factory=list)
    """(exact Hessian, bending added, shift, lambda_min_rel or 'failed') per factorization"""
    dfdx_s: float = 0.0
    """wall time of assembling ∂F/∂X for the presses (``press_matrix``; 0 without) [s]"""
    regularization_effect: float = 0.0
    """relative residual ||K s - b|| / ||b|| of the latest columns s in the
    unregularized system (the regularization's cost to the prediction; 0
    when none was applied, NaN before any columns)"""

    @property
    def regularized(self) -> bool:
        """Whether the factored matrix differs from the model's exact linearisation."""
        return bool(self.bend_added or self.shift or not self.exact_hessian)

    @property
    def regularization(self) -> str:
        """In words, for logs and the node's status: 'none', or what was added and why."""
        if not self.regularized:
            return "none"
        parts = []
        if self.bend_added:
            parts.append(f"+{self.bend_added:.2g} N m bending")
        if self.shift:
            parts.append(f"shift {self.shift:.2g} N/m")
        if not self.exact_hessian:
            parts.append("compression-projected Hessian")
        why = self.fallback or "bend_floor requested"
        eff = "" if not np.isfinite(self.regularization_effect) else f"; effect {self.regularization_effect:.1e}"
        return ", ".join(parts) + f" ({why}{eff})"


def rigid_modes(x: np.ndarray) -> np.ndarray:
    """Six rigid motions of the points x (p, 3) as columns (3p, 6): translations,
    then rotations about the centroid."""
    c = x.mean(axis=0)
    r = x - c
    B = np.zeros((len(x), 3, 6))
    for a in range(3):
        B[:, a, a] = 1.0
        e = np.zeros(3)
        e[a] = 1.0
        B[:, :, 3 + a] = np.cross(e, r)
    return B.reshape(-1, 6)


def contact_curvature(model: ClothModel, x: np.ndarray, h: float = 1e-6) -> sp.csr_matrix | None:
    """The body-curvature part of the contact Hessian, ``-k_c pen Hess(phi)``
    (3n, 3n), for a body without ``phi_hess``: couture.cloth's exact Hessian
    (``stiffness(project=False)``) includes it for bodies that give their SDF
    Hessian, and leaves it out for the others.

    Without it a rigid spin of a garment on a frictionless body of revolution
    is not in the kernel of K, and sensitivities on curved bodies are off by
    O(contact pressure / radius). Hess(phi) by central differences of the
    body's gradient (exact for analytic bodies up to O(h²)). None when the
    model has no contact term or its body has ``phi_hess``.
    """
    if "contact" not in model.terms or model.body is None or hasattr(model.body, "phi_hess"):
        return None
    phi, _ = model.body.phi_grad(x)
    pen = model.contact_offset - np.asarray(phi)
    act = np.nonzero(pen > 0)[0]
    if len(act) == 0:
        return None
    p = x[act]
    H = np.empty((len(act), 3, 3))
    for a in range(3):
        e = np.zeros(3)
        e[a] = h
        _, gp = model.body.phi_grad(p + e)
        _, gm = model.body.phi_grad(p - e)
        H[:, :, a] = (np.asarray(gp) - np.asarray(gm)) / (2 * h)
    H = 0.5 * (H + H.transpose(0, 2, 1))
    blk = -model.contact_normal_force(pen[act])[:, None, None] * H
    r = 3 * act[:, None, None] + np.arange(3)[None, :, None]
    c = 3 * act[:, None, None] + np.arange(3)[None, None, :]
    n3 = 3 * model.n
    return sp.csr_matrix(
        (blk.ravel(), (np.broadcast_to(r, blk.shape).ravel(), np.broadcast_to(c, blk.shape).ravel())), shape=(n3, n3)
    )


def find_null_modes(K: sp.spmatrix, x: np.ndarray, tol: float = 1e-8) -> np.ndarray:
    """Rigid motions of x (p, 3) annihilated by K (3p, 3p): an orthonormal basis
    (3p, k), k ≤ 6, of the combinations c with ||K B c|| < tol * median diag(K)."""
    B = rigid_modes(x)
    Qb, Rb = np.linalg.qr(B)
    keep = np.abs(np.diag(Rb)) > 1e-12 * np.abs(Rb).max()
    Qb = Qb[:, keep]
    KB = np.asarray(K @ Qb)
    _, s, Vt = np.linalg.svd(KB, full_matrices=False)
    scale = float(np.median(np.abs(K.diagonal()))) or 1.0
    null = s < tol * scale
    if not np.any(null):
        return np.zeros((K.shape[0], 0))
    N = Qb @ Vt[null].T
    N, _ = np.linalg.qr(N)
    return N


class SensitivityFactor:
    """Factorization of the (floored) stiffness at an equilibrium ``x_eq`` of ``model``.

    ``solve(rhs)`` applies K⁻¹ on free DOFs; ``columns(psi)`` and
    ``param_column(dX)`` give design sensitivities. Build it in idle time
    (a worker thread): it costs one stiffness assembly, one sparse
    factorization and a handful of back-substitutions (``info.refactor_s``).

    With ``press_matrix`` (default) it also assembles ∂F/∂X at x_eq
    (:class:`~couture.sensitivity.dfdx.DForcesDX`, ``info.dfdx_s``), so a
    press's right-hand side is one sparse product instead of a matrix-free
    evaluation of every term; the columns of one Ψ are kept (the last
    ``keep_columns`` Ψs), so a second press with the same Ψ on this
    factorization costs a copy. Without it, presses use ``model.dforces_dX``
    (a factor made for one set of columns, e.g. a GMLS sample, saves the
    assembly that way).
    """

    def __init__(
        self,
        model: ClothModel,
        x_eq: np.ndarray,
        bend_floor: bool = False,
        *,
        exact_hessian: bool = True,
        floor_factor: float = 1e-4,
        length: float | None = None,
        singular_tol: float = 1e-10,
        null_tol: float = 1e-8,
        check: bool = True,
        backend: str = "auto",
        seed: int = 0,
        press_matrix: bool = True,
        keep_columns: int = 8,
    ):
        t0 = time.perf_counter()
        self.model = model
        self.x_eq = np.array(x_eq, dtype=np.float64, copy=True)
        n = model.n
        free = np.asarray(model.free, bool)
        self.n = n
        self.dofs = (3 * np.nonzero(free)[0][:, None] + np.arange(3)[None, :]).ravel()
        info = FactorInfo(n_dofs=len(self.dofs))

        def stiffness(project):
            K = sp.csr_matrix(model.stiffness(self.x_eq, project=project))
            if project is False:
                C = contact_curvature(model, self.x_eq)
                if C is not None:
                    K = K + C
            return K[self.dofs][:, self.dofs].tocsr()

        # the exact Hessian is the true linearisation (PSD at a stable
        # equilibrium); the compression-projected one is the fallback
        mats = {}

        def base(exact):
            if exact not in mats:
                mats[exact] = stiffness(False if exact else None)
            return mats[exact]

        Kff = base(exact_hessian)
        self.N = find_null_modes(Kff, self.x_eq[free], null_tol)
        info.null_modes = self.N.shape[1]
        if info.null_modes:
            _, _, piv = sla.qr(self.N.T, mode="economic", pivoting=True)
            gauge = np.sort(piv[: info.null_modes])
        else:
            gauge = np.zeros(0, np.int64)
        self.keep = np.setdiff1d(np.arange(len(self.dofs)), gauge)

        k_b, Q = model_bending(model)
        L = length if length is not None else length_scale(model.X)
        lam, mu = model_lame(model)
        k_floor = floor_factor * (lam + mu) * L * L
        info.bend_stiffness, info.bend_floor = k_b, k_floor
        Qf = sp.kron(Q, sp.identity(3), format="csr")[self.dofs][:, self.dofs]
        self.scale = float(np.median(np.abs(Kff.diagonal()))) or 1.0

        add0 = max(k_floor - k_b, 0.0) if bend_floor else 0.0
        thick = [a for a in (max(k_floor - k_b, 0.0), max(100.0 * k_floor - k_b, 0.0)) if a > add0]
        plan = [(exact_hessian, add0, 0.0)]
        if exact_hessian:
            plan.append((False, add0, 0.0))  # only tried when the exact one is indefinite
        rng = np.random.default_rng(seed)
        reasons = []
        projected = not exact_hessian
        i = 0
        while i < len(plan):
            exact, add, shift = plan[i]
            i += 1
            if not exact and not projected:
                continue  # exact Hessian factored fine: no need for the projected one
            A = base(exact)
            if add:
                A = A + add * Qf
            if shift:
                A = A + shift * sp.identity(A.shape[0], format="csr")
            A = A[self.keep][:, self.keep].tocsc() if info.null_modes else A.tocsc()
            tf = time.perf_counter()
            try:
                fac = _factorize(A, backend)
            except FactorizationError as e:
                info.factor_s += time.perf_counter() - tf
                info.attempts.append((exact, add, shift, "failed"))
                if exact and exact_hessian and not projected:
                    projected = True
                    reasons.append("exact Hessian indefinite, used the compression-projected one")
                    continue
                reasons.append(f"factorization failed with +{add:.3g} N m bending ({e})")
                lam_rel = 0.0
            else:
                info.factor_s += time.perf_counter() - tf
                lam_rel = self._lambda_min(fac, A, rng) / self.scale if check else float("nan")
                info.attempts.append((exact, add, shift, lam_rel))
                self._fac, self._A = fac, A
                info.bend_added, info.shift, info.lambda_min_rel = add, shift, lam_rel
                info.backend = getattr(fac, "backend", "splu")
                info.exact_hessian = bool(exact)
                if not check or lam_rel >= singular_tol:
                    break
                reasons.append(f"near-singular (lambda_min/median diag = {lam_rel:.2e} with +{add:.3g} N m bending)")
            # escalate: thicker bending, then a small diagonal shift
            ex = exact and not projected
            if thick:
                plan.append((ex, thick.pop(0), 0.0))
            elif shift == 0.0:
                plan.append((ex, max(add, add0), 1e-8 * self.scale))
        if not hasattr(self, "_fac"):
            raise FactorizationError("; ".join(reasons))
        if reasons:
            info.fallback = (
                "; ".join(reasons)
                + f" -> used +{info.bend_added:.3g} N m bending"
                + (f", shift {info.shift:.3g} N/m" if info.shift else "")
            )
        # the unregularized matrix, kept to measure the regularization's effect
        self._A_exact = None
        if info.regularized:
            A0 = base(exact_hessian)
            self._A_exact = A0[self.keep][:, self.keep].tocsr() if info.null_modes else A0
            info.regularization_effect = float("nan")
        self.dfdx: DForcesDX | None = None
        if press_matrix:
            self.dfdx = DForcesDX(model, self.x_eq, self.dofs)
            info.dfdx_s = self.dfdx.assemble_s
        self._keep = keep_columns
        self._columns: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        """hash of Ψ -> (Ψ, its columns), the last ``keep_columns``"""
        info.refactor_s = time.perf_counter() - t0
        self.info = info

    def dforces_dX(self, dX: np.ndarray) -> np.ndarray:
        """∂F/∂X · dX (n, 3) [N per unit of dX] at x_eq, dX (n, 2)."""
        return self.model.dforces_dX(self.x_eq, dX)

    @staticmethod
    def _lambda_min(fac, A, rng, iters: int = 6) -> float:
        """Upper estimate of the smallest eigenvalue of A by inverse iteration."""
        v = rng.standard_normal(A.shape[0])
        v /= np.linalg.norm(v)
        lam = np.inf
        for _ in range(iters):
            w = fac.solve(v)
            nw = float(np.linalg.norm(w))
            if not np.isfinite(nw) or nw == 0:
                return 0.0
            lam = 1.0 / nw
            v = w / nw
        # Rayleigh quotient of the last iterate is a tighter upper bound
        return float(min(lam, v @ (A @ v)))

    # -- solves -----------------------------------------------------------
    def solve_free(self, b: np.ndarray) -> np.ndarray:
        """K⁻¹ b on free DOFs, b (n_dofs,) or (n_dofs, k), free modes projected out."""
        b = np.asarray(b, dtype=np.float64)
        N = self.N
        if N.shape[1]:
            b = b - N @ (N.T @ b)
            y = np.zeros_like(b)
            y[self.keep] = self._fac.solve(np.ascontiguousarray(b[self.keep]))
            return y - N @ (N.T @ y)
        return self._fac.solve(b)

    def _measure_effect(self, b: np.ndarray, y: np.ndarray) -> None:
        """Record ||K y - b|| / ||b|| in the unregularized K (free DOFs, b and y (m,) or (m, k))."""
        if self._A_exact is None:
            return
        if self.N.shape[1]:
            b = b - self.N @ (self.N.T @ b)
            b, y = b[self.keep], y[self.keep]
        nb = float(np.linalg.norm(b))
        if nb > 0:
            self.info.regularization_effect = float(np.linalg.norm(self._A_exact @ y - b)) / nb

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """K⁻¹ rhs for rhs (n, 3) or (n, 3, k) forces; pinned vertices get 0."""
        rhs = np.asarray(rhs, dtype=np.float64)
        k = rhs.shape[2:] if rhs.ndim == 3 else ()
        flat = rhs.reshape(3 * self.n, -1)
        out = np.zeros_like(flat)
        out[self.dofs] = self.solve_free(flat[self.dofs])
        return out.reshape((self.n, 3) + tuple(k))

    def correction(self, forces: np.ndarray) -> np.ndarray:
        """K⁻¹ forces (n, 3): the Newton correction of a state whose out-of-balance
        forces at the edited rest shape are ``forces`` (the factor at the
        equilibrium as the chord: one back-substitution)."""
        return self.solve(forces)

    def rhs_free(self, dX: np.ndarray) -> np.ndarray:
        """∂F/∂X · dX on the free DOFs: (n_dofs,) for dX (n, 2), (n_dofs, k) for
        (n, 2, k); one sparse product with ``press_matrix``, else ``model.dforces_dX``
        per column."""
        dX = np.asarray(dX, dtype=np.float64)
        if self.dfdx is not None:
            return self.dfdx.apply(dX)
        if dX.ndim == 2:
            return self.dforces_dX(dX).reshape(-1)[self.dofs]
        rhs = np.stack([self.dforces_dX(dX[:, :, j]) for j in range(dX.shape[2])], axis=2)
        return rhs.reshape(3 * self.n, -1)[self.dofs]

    def columns(self, psi: np.ndarray) -> np.ndarray:
        """Response columns S (n, 3, 2) for a pointer Jacobian psi (n, 2, 2):
        S[:, :, j] = ∂x/∂d_j = K⁻¹ ∂F/∂X · psi[:, :, j]. The columns of the
        last ``keep_columns`` Ψs are kept: the same Ψ again returns a copy."""
        psi = np.asarray(psi, dtype=np.float64)
        key = hash((psi.shape, psi.tobytes()))
        hit = self._columns.get(key)
        if hit is not None and np.array_equal(hit[0], psi):
            return hit[1].copy()
        k = psi.shape[2]
        live = [j for j in range(k) if np.any(psi[:, :, j])]  # a parameter edit has one zero column
        S = np.zeros((self.n, 3, k))
        if live:
            b = self.rhs_free(psi[:, :, live])
            y = self.solve_free(b)
            S.reshape(3 * self.n, k)[np.ix_(self.dofs, np.array(live))] = y
            self._measure_effect(b, y)
        if self._keep > 0:
            if len(self._columns) >= self._keep:
                self._columns.pop(next(iter(self._columns)))
            self._columns[key] = (psi.copy(), S.copy())
        return S

    def clear_columns(self) -> None:
        """Forget the kept columns (the next press computes them; for benchmarks)."""
        self._columns.clear()

    def param_column(self, dX_dg: np.ndarray) -> np.ndarray:
        """Sensitivity s_g (n, 3) = ∂x/∂g for a sloper parameter with rest motion dX/dg (n, 2)."""
        b = self.rhs_free(np.asarray(dX_dg, dtype=np.float64).reshape(self.n, 2))
        y = self.solve_free(b)
        s = np.zeros(3 * self.n)
        s[self.dofs] = y
        self._measure_effect(b, y)
        return s.reshape(self.n, 3)
