"""Progressive nonlinear model (SC §4): a cache of drape samples blended by
generalized moving least squares (GMLS), plus plain MLS and linear prediction.

Samples live at design points d (2,) — the pointer motion of the active edit
in metres of pattern space (what Ψ multiplies), or a sloper parameter change.
A sample holds the drape x^m (n, 3) (zeroth order) and optionally its
sensitivity columns s_j^m = ∂x/∂d_j (n, 3, 2) (first order).

SC §4 formulas, exactly, with basis p = (1, d1, d2) and weight
``w = 1 / (|d - d^m|² + ε²)``, ε² = 1e-3:

    x(d) = Σ_m N^m(d) x^m + Σ_m Σ_j N_j^m(d) s_j^m
    N^m  = p(d)ᵀ G⁻¹ p(d^m) w_m,   N_j^m = p(d)ᵀ G⁻¹ ∂p/∂d_j w_m
    G    = Σ_m w_m p(d^m) p(d^m)ᵀ + Σ_{m first order} w_m Σ_j ∂p/∂d_j ∂p/∂d_jᵀ

ε² = 1e-3 is in squared units of d. With d in metres, ε ≈ 3 cm: samples
closer than that are blended, farther ones dominate near themselves.
``d_scale`` [units of d] rescales d before weighting (u = d / d_scale), for
edits whose natural unit differs (a parameter in cm, a dimensionless ratio).
The weight is finite at a sample (by design), so GMLS is a weighted
least-squares fit, not an interpolant: it reproduces a sample exactly only
when the samples agree with one linear field (or as ε → 0).

Consistent derivatives (``GMLSCache(consistent=True)``, the default): SC's
GMLS trusts the columns s^m, and with d in metres their terms outweigh the
values' by about 1/|Δd|² (≈ 1600 for samples 2.5 cm apart), so the fitted
slope is the columns' average. With friction the columns are the stick
response (anchors held) and a few cm of edit make the cloth slip: on the
default skirt lengthened 5 cm, with the press sample and a converged one at
2.5 cm, GMLS followed the stiff columns (12.5 mm RMS from the true drape)
where MLS, values alone, was at 1 mm. Each pair of first-order samples is
checked against the trapezoid identity (exact for fields quadratic along the
pair): its relative defect r (the error of predicting one sample's value from
the other's value and both columns, over the value change) is ≈ 0.8 there,
0.05 on SC's frictionless Fig. 5 sheet. The columns are moved by the least
change that removes the part φ = r² / (r² + r₀²) of each pair's defect
(r₀ = ``defect_scale`` = 0.1; :func:`consistent_derivatives`): columns that
explain the values are kept, wrong ones move to the secants along the pairs
and keep their components across them. The correction is a change of the
coefficients, so prediction reads the same rows as before; the defects are
computed when a sample is added.

Evaluation is a 3×3 solve (plus, with consistent derivatives, O(M²) to fold
the correction in; its pseudo-inverse, at most 15×12, is made once per set of
active samples) and one weighted sum of a few (3n,) rows (``predict`` reads
at most ``max_active`` samples, nearest first).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numba import njit


@njit(cache=True)
def gmls_coefficients(d, D, has_first, eps2, d_scale, ridge, c0, c1):
    """Shape functions at d (2,) for samples at D (M, 2): c0 (M,) multiplies x^m,
    c1 (M, 2) multiplies s_j^m (in units of d). Coordinates are centred at d,
    so p(d) = (1, 0, 0) and only the first column of G⁻¹ is needed.
    ``ridge`` (relative to trace G) regularises the slope block only when G is
    degenerate (MLS with collinear samples: the unresolved slope is set to ~0)."""
    M = D.shape[0]
    G = np.zeros((3, 3))
    for m in range(M):
        u0 = (D[m, 0] - d[0]) / d_scale
        u1 = (D[m, 1] - d[1]) / d_scale
        w = 1.0 / (u0 * u0 + u1 * u1 + eps2)
        G[0, 0] += w
        G[0, 1] += w * u0
        G[0, 2] += w * u1
        G[1, 1] += w * u0 * u0
        G[1, 2] += w * u0 * u1
        G[2, 2] += w * u1 * u1
        if has_first[m]:
            G[1, 1] += w
            G[2, 2] += w
    G[1, 0] = G[0, 1]
    G[2, 0] = G[0, 2]
    G[2, 1] = G[1, 2]
    for attempt in range(2):
        # first column of G^-1 by cofactors (G symmetric)
        a00 = G[1, 1] * G[2, 2] - G[1, 2] * G[2, 1]
        a10 = -(G[1, 0] * G[2, 2] - G[1, 2] * G[2, 0])
        a20 = G[1, 0] * G[2, 1] - G[1, 1] * G[2, 0]
        det = G[0, 0] * a00 + G[0, 1] * a10 + G[0, 2] * a20
        tr = G[0, 0] + G[1, 1] + G[2, 2]
        if abs(det) > 1e-10 * tr * tr * tr or attempt == 1:
            break
        # degenerate (MLS with < 3 non-collinear samples): regularise the slopes
        G[1, 1] += ridge * tr
        G[2, 2] += ridge * tr
    q0 = a00 / det
    q1 = a10 / det
    q2 = a20 / det
    for m in range(M):
        u0 = (D[m, 0] - d[0]) / d_scale
        u1 = (D[m, 1] - d[1]) / d_scale
        w = 1.0 / (u0 * u0 + u1 * u1 + eps2)
        c0[m] = w * (q0 + q1 * u0 + q2 * u1)
        if has_first[m]:
            c1[m, 0] = w * q1 * d_scale
            c1[m, 1] = w * q2 * d_scale
        else:
            c1[m, 0] = 0.0
            c1[m, 1] = 0.0


@njit(cache=True)
def trapezoid_defect(A, rows_m, rows_k, dd):
    """(|D|², |x^k - x^m|²) for two first-order samples, rows (x, s_1, s_2) of A,
    Δd = dd (2,): D = x^k - x^m - ½ (s^m + s^k)·Δd, summed over all entries."""
    dn = 0.0
    xn = 0.0
    for i in range(A.shape[1]):
        dx = A[rows_k[0], i] - A[rows_m[0], i]
        s0 = A[rows_m[1], i] + A[rows_k[1], i]
        s1 = A[rows_m[2], i] + A[rows_k[2], i]
        e = dx - 0.5 * (s0 * dd[0] + s1 * dd[1])
        dn += e * e
        xn += dx * dx
    return dn, xn


def defect_weight(defect2: float, change2: float, defect_scale: float) -> float:
    """φ = r² / (r² + r₀²) for the relative trapezoid defect r = |D| / |x^k - x^m|
    and r₀ = ``defect_scale``: the part of a pair's defect charged to the columns."""
    if change2 <= 0.0:
        return 0.0
    r2 = defect2 / change2
    return r2 / (r2 + defect_scale * defect_scale)


@njit(cache=True)
def consistent_derivatives(D, has_first, phi, c0, c1):
    """Fold the derivative consistency correction into GMLS coefficients (in place).

    Values x^m are converged solves; the columns s^m are linearisations that can
    miss what a finite edit does (friction: ``SensitivityFactor`` holds the
    anchors, so s^m is the stick response, while a few cm of edit make hundreds
    of anchors slip). Along the segment between two first-order samples m, k
    the trapezoid identity

        x^k - x^m = ½ (s^m + s^k) · (d^k - d^m)

    holds exactly for any field quadratic along it, and its defect
    D_mk = x^k - x^m - ½ (s^m + s^k)·Δd is the error of predicting one sample's
    value from the other's value and both columns (leave one value out). The
    columns used are s̃^m = s^m + C^m, C the least-norm least-squares solution of

        ½ (C^m + C^k)·Δd/|Δd| = φ_mk D_mk/|Δd|     over all first-order pairs

    (slope units: no scale of d enters); φ_mk = phi[m, k] in [0, 1] is the
    part of the defect charged to the columns (:func:`defect_weight`: ~0 for a
    relative defect well under ``defect_scale``, ~1 well over it). With φ = 1
    wrong columns move to the secants along the pairs; components the pairs
    do not see (across a line of collinear samples) stay as computed.

    s̃ is linear in the stored rows, so the correction is a change of the
    coefficients c0 (M,) (on x^m) and c1 (M, 2) (on s^m) of the same rows:
    for each pair q = (m, k), g_q = φ_q Σ c1 · A⁺[:, q] / |Δd_q| adds g_q to
    c0[k], -g_q to c0[m] and -½ g_q Δd_q to c1[m] and c1[k]."""
    K, pm, pk = consistency_operator(D, has_first, phi)
    fold_consistency(D, K, pm, pk, c0, c1)


@njit(cache=True)
def consistency_operator(D, has_first, phi):
    """The query-independent part of :func:`consistent_derivatives` for samples at
    D (M, 2): (K (P, M, 2), pm (P,), pk (P,)) over the P first-order pairs (pm < pk),
    with g_q = Σ c1 · K[q] (K = φ_q A⁺ / |Δd_q|, zero for coincident samples)."""
    M = D.shape[0]
    idx = np.full(M, -1, np.int64)
    F = 0
    for m in range(M):
        if has_first[m]:
            idx[m] = F
            F += 1
    P = F * (F - 1) // 2
    K = np.zeros((P, M, 2))
    pm = np.zeros(P, np.int64)
    pk = np.zeros(P, np.int64)
    if P == 0:
        return K, pm, pk
    A = np.zeros((P, 2 * F))
    h = np.zeros(P)
    scale = 0.0
    for m in range(M):
        scale = max(scale, abs(D[m, 0]), abs(D[m, 1]))
    q = 0
    for m in range(M):
        if not has_first[m]:
            continue
        for k in range(m + 1, M):
            if not has_first[k]:
                continue
            dd0 = D[k, 0] - D[m, 0]
            dd1 = D[k, 1] - D[m, 1]
            hq = np.sqrt(dd0 * dd0 + dd1 * dd1)
            pm[q] = m
            pk[q] = k
            if hq > 1e-12 * scale:  # coincident samples say nothing about slopes
                h[q] = hq
                A[q, 2 * idx[m]] = 0.5 * dd0 / hq
                A[q, 2 * idx[m] + 1] = 0.5 * dd1 / hq
                A[q, 2 * idx[k]] = 0.5 * dd0 / hq
                A[q, 2 * idx[k] + 1] = 0.5 * dd1 / hq
            q += 1
    Ap = np.linalg.pinv(A, 1e-10)  # (2F, P)
    for q in range(P):
        w = phi[pm[q], pk[q]]
        if h[q] == 0.0 or w == 0.0:
            continue
        for i in range(M):
            if has_first[i]:
                K[q, i, 0] = w * Ap[2 * idx[i], q] / h[q]
                K[q, i, 1] = w * Ap[2 * idx[i] + 1, q] / h[q]
    return K, pm, pk


@njit(cache=True)
def fold_consistency(D, K, pm, pk, c0, c1):
    """c0, c1 (in place) += the consistency correction with operator K (see
    :func:`consistency_operator`); O(P M) per query."""
    M = c1.shape[0]
    for q in range(K.shape[0]):
        g = 0.0
        for i in range(M):
            g += c1[i, 0] * K[q, i, 0] + c1[i, 1] * K[q, i, 1]
        if g == 0.0:
            continue
        m, k = pm[q], pk[q]
        dd0 = D[k, 0] - D[m, 0]
        dd1 = D[k, 1] - D[m, 1]
        c0[k] += g
        c0[m] -= g
        c1[m, 0] -= 0.5 * g * dd0
        c1[m, 1] -= 0.5 * g * dd1
        c1[k, 0] -= 0.5 * g * dd0
        c1[k, 1] -= 0.5 * g * dd1


@njit(cache=True)
def weighted_rows(A, rows, coef, out):
    """out (L,) float64 = Σ_k coef[k] * A[rows[k]] (A (R, L) float32 or float64)."""
    L = A.shape[1]
    for i in range(L):
        out[i] = 0.0
    for k in range(rows.shape[0]):
        c = coef[k]
        if c != 0.0:
            r = rows[k]
            for i in range(L):
                out[i] += c * A[r, i]


@dataclass
class Sample:
    d: np.ndarray
    """design point (2,) [units of d]"""
    row_x: int
    rows_s: tuple[int, int] | None
    t: float
    """time.monotonic() at insertion [s]"""
    anchor: bool = False
    """the press equilibrium (the linear predictor's base)"""
    uid: int = 0
    """unique within its cache (keys the pair weights φ)"""


class GMLSCache:
    """Samples (d^m, x^m[, s^m]) under a memory cap, with GMLS / MLS / linear prediction.

    ``max_bytes`` and ``max_samples`` cap storage; when a new sample does not
    fit, the sample with the largest ``|d^m - d_now| / d_scale + age / age_scale``
    is evicted (d_now: the latest pointer seen), never the newest nor the one
    nearest the pointer.
    """

    def __init__(
        self,
        n: int,
        *,
        max_bytes: int = 64 << 20,
        max_samples: int = 16,
        eps2: float = 1e-3,
        d_scale: float = 1.0,
        max_active: int = 6,
        dtype=np.float32,
        age_scale: float = 30.0,
        ridge: float = 1e-6,
        consistent: bool = True,
        defect_scale: float = 0.1,
    ):
        self.n = int(n)
        self.max_bytes = int(max_bytes)
        self.max_samples = int(max_samples)
        self.eps2 = float(eps2)
        self.d_scale = float(d_scale)
        self.max_active = int(max_active)
        self.dtype = np.dtype(dtype)
        self.age_scale = float(age_scale)
        self.ridge = float(ridge)
        self.consistent = bool(consistent)
        """GMLS reads each sample's columns corrected to agree with the other
        samples' values (:func:`consistent_derivatives`); False: SC's GMLS as is"""
        if not defect_scale > 0.0:
            raise ValueError(f"GMLSCache: defect_scale must be > 0, got {defect_scale}")
        self.defect_scale = float(defect_scale)
        """r₀ of :func:`defect_weight`: the relative trapezoid defect at which half of
        it is charged to the columns"""
        self._pair_defect: dict[tuple[int, int], tuple[float, float]] = {}
        self._operator: tuple | None = None
        self._uid = 0
        self.samples: list[Sample] = []
        self._row_bytes = 3 * self.n * self.dtype.itemsize
        cap_rows = max(1, min(3 * self.max_samples, self.max_bytes // self._row_bytes))
        self._A = np.empty((0, 3 * self.n), self.dtype)
        self._cap_rows = cap_rows
        self._free_rows: list[int] = []
        self._d_now = np.zeros(2)
        self._out = np.empty(3 * self.n)

    # -- storage ----------------------------------------------------------
    @property
    def nbytes(self) -> int:
        """bytes held by sample data"""
        return sum(self._row_bytes * (1 + (2 if s.rows_s else 0)) for s in self.samples)

    def __len__(self) -> int:
        return len(self.samples)

    def _take_row(self) -> int:
        if self._free_rows:
            return self._free_rows.pop()
        r = len(self._A)
        grow = max(4, min(len(self._A), self._cap_rows - len(self._A)))
        A = np.empty((len(self._A) + grow, 3 * self.n), self.dtype)
        A[: len(self._A)] = self._A
        self._free_rows.extend(range(len(A) - 1, r, -1))
        self._A = A
        return r

    def _evict_one(self, protect: set[int]) -> bool:
        if not self.samples:
            return False
        now = time.monotonic()
        best, score = None, -np.inf
        for i, s in enumerate(self.samples):
            if i in protect:
                continue
            sc = float(np.linalg.norm(s.d - self._d_now)) / self.d_scale + (now - s.t) / self.age_scale
            if sc > score:
                best, score = i, sc
        if best is None:
            return False
        s = self.samples.pop(best)
        self._forget_pairs(s.uid)
        self._free_rows.append(s.row_x)
        if s.rows_s:
            self._free_rows.extend(s.rows_s)
        return True

    def _forget_pairs(self, uid: int) -> None:
        for key in [k for k in self._pair_defect if uid in k]:
            del self._pair_defect[key]

    def clear(self) -> None:
        self.samples.clear()
        self._pair_defect.clear()
        self._A = np.empty((0, 3 * self.n), self.dtype)
        self._free_rows = []

    def add(self, d, x: np.ndarray, S: np.ndarray | None = None, *, anchor: bool = False) -> bool:
        """Add a sample: drape x (n, 3) at d (2,), optionally its columns S (n, 3, 2).
        Evicts as needed; returns False (nothing stored) if it cannot fit at all."""
        d = np.asarray(d, dtype=np.float64).reshape(2)
        need = self._row_bytes * (3 if S is not None else 1)
        if need > self.max_bytes:
            return False
        if anchor:
            for s in self.samples:
                s.anchor = False

        def nearest_idx():
            if not self.samples:
                return -1
            return int(np.argmin([np.linalg.norm(s.d - self._d_now) for s in self.samples]))

        while self.samples and (len(self.samples) + 1 > self.max_samples or self.nbytes + need > self.max_bytes):
            prot = {len(self.samples) - 1, nearest_idx()}
            if not self._evict_one(prot):
                if not self._evict_one(set()):
                    break
        rx = self._take_row()
        self._A[rx] = np.asarray(x, dtype=np.float64).reshape(-1)
        rs = None
        if S is not None:
            S = np.asarray(S, dtype=np.float64)
            rs = (self._take_row(), self._take_row())
            self._A[rs[0]] = S[:, :, 0].reshape(-1)
            self._A[rs[1]] = S[:, :, 1].reshape(-1)
        self._uid += 1
        new = Sample(d=d, row_x=rx, rows_s=rs, t=time.monotonic(), anchor=anchor, uid=self._uid)
        if rs is not None:  # trapezoid defects with every first-order sample (O(n) each, here, not at drag time)
            rows_k = np.array([rx, *rs], np.int64)
            for s in self.samples:
                if s.rows_s is not None:
                    self._pair_defect[(s.uid, new.uid)] = trapezoid_defect(
                        self._A, np.array([s.row_x, *s.rows_s], np.int64), rows_k, new.d - s.d
                    )
        self.samples.append(new)
        return True

    # -- prediction -------------------------------------------------------
    def _active(self, d):
        """The ``max_active`` samples nearest d (all of them when fewer)."""
        ss = self.samples
        if len(ss) > self.max_active:
            dist = np.array([np.sum((s.d - d) ** 2) for s in ss])
            ss = [ss[i] for i in np.argsort(dist)[: self.max_active]]
        return ss

    def coefficients(self, d, method: str = "gmls"):
        """(samples, c0 (M,), c1 (M, 2)) shape functions at d for 'gmls' or 'mls'."""
        d = np.asarray(d, dtype=np.float64).reshape(2)
        ss = self._active(d)
        M = len(ss)
        D = np.empty((M, 2))
        first = np.zeros(M, np.bool_)
        for i, s in enumerate(ss):
            D[i] = s.d
            first[i] = s.rows_s is not None and method == "gmls"
        c0 = np.empty(M)
        c1 = np.empty((M, 2))
        gmls_coefficients(d, D, first, self.eps2, self.d_scale, self.ridge, c0, c1)
        if method == "gmls" and self.consistent:
            # the operator depends on the active samples only: kept while they stay
            key = (tuple(s.uid for s in ss), tuple(first.tolist()), self.defect_scale)
            if self._operator is None or self._operator[0] != key:
                self._operator = (key, *consistency_operator(D, first, self.pair_weights(ss)))
            _, K, pm, pk = self._operator
            fold_consistency(D, K, pm, pk, c0, c1)
        return ss, c0, c1

    def pair_weights(self, ss: list[Sample]) -> np.ndarray:
        """φ (M, M) of :func:`defect_weight` for every first-order pair of ``ss`` (upper triangle)."""
        M = len(ss)
        phi = np.zeros((M, M))
        for i in range(M):
            for k in range(i + 1, M):
                key = (ss[i].uid, ss[k].uid) if ss[i].uid < ss[k].uid else (ss[k].uid, ss[i].uid)
                dc = self._pair_defect.get(key)
                if dc is not None:
                    phi[i, k] = defect_weight(dc[0], dc[1], self.defect_scale)
        return phi

    def predict(self, d, method: str = "gmls") -> np.ndarray:
        """Predicted drape x (n, 3) float64 at d by 'gmls' (zeroth + first order
        samples) or 'mls' (zeroth order only)."""
        if not self.samples:
            raise ValueError("GMLSCache.predict: no samples")
        d = np.asarray(d, dtype=np.float64).reshape(2)
        self._d_now = d
        ss, c0, c1 = self.coefficients(d, method)
        rows, coef = [], []
        for s, a, b in zip(ss, c0, c1, strict=True):
            rows.append(s.row_x)
            coef.append(a)
            if s.rows_s is not None and method == "gmls":
                rows.extend(s.rows_s)
                coef.extend(b)
        out = np.empty(3 * self.n)
        weighted_rows(self._A, np.asarray(rows, np.int64), np.asarray(coef, np.float64), out)
        return out.reshape(self.n, 3)

    def anchor(self) -> Sample | None:
        for s in self.samples:
            if s.anchor:
                return s
        return next((s for s in self.samples if s.rows_s is not None), None)

    def predict_linear(self, d, sample: Sample | None = None) -> np.ndarray:
        """Linear sensitivity x^0 + S^0 (d - d^0) about the anchor (press) sample."""
        s = sample or self.anchor()
        if s is None or s.rows_s is None:
            raise ValueError("GMLSCache.predict_linear: no first-order sample")
        d = np.asarray(d, dtype=np.float64).reshape(2)
        self._d_now = d
        dd = d - s.d
        out = np.empty(3 * self.n)
        weighted_rows(
            self._A, np.array([s.row_x, s.rows_s[0], s.rows_s[1]], np.int64), np.array([1.0, dd[0], dd[1]]), out
        )
        return out.reshape(self.n, 3)
