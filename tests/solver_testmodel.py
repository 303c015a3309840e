"""A small stand-in for ``couture.cloth.model.ClothModel`` used by the solver tests.

Mass-spring membrane on mesh edges (PSD-projected spring Hessians), Bergou
isometric bending (constant Hessian, flat rest state), lumped mass from an
areal density, gravity, zero-length seam penalty springs, an optional
analytic sphere body with penalty contact, pins. It implements exactly the
ClothModel contract the solvers use, so the solvers can be developed and
tested without the real cloth package; the real model replaces it in the
tests once it exists.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from couture.mesh import GarmentMesh


class SphereBody:
    """Analytic sphere: ``phi_grad(points) -> (phi, grad)``; phi > 0 outside [m]."""

    def __init__(self, center, radius: float):
        self.center = np.asarray(center, np.float64)
        self.radius = float(radius)

    def phi_grad(self, points: np.ndarray):
        d = points - self.center
        r = np.linalg.norm(d, axis=1)
        g = d / np.maximum(r, 1e-12)[:, None]
        return r - self.radius, g


def _edges_and_hinges(tris: np.ndarray):
    e = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    opp = np.concatenate([tris[:, 2], tris[:, 0], tris[:, 1]])
    tri_id = np.concatenate([np.arange(len(tris))] * 3)
    key = e[:, 0].astype(np.int64) * (tris.max() + 1) + e[:, 1]
    order = np.argsort(key, kind="stable")
    key_s = key[order]
    uniq, first = np.unique(key_s, return_index=True)
    edges = e[order][first]
    hinges = []
    for a, b in zip(first, np.append(first[1:], len(key_s))):
        if b - a == 2:
            i, j = order[a], order[a + 1]
            hinges.append((e[i, 0], e[i, 1], opp[i], opp[j], tri_id[i], tri_id[j]))
    return edges, np.array(hinges, dtype=np.int64).reshape(-1, 6)


def _cot(u, v):
    c = np.einsum("ij,ij->i", u, v)
    s = np.linalg.norm(np.cross(u, v), axis=1) if u.shape[1] == 3 else np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])
    return c / np.maximum(s, 1e-300)


class SpringSheetModel:
    """ClothModel stand-in. Parameters in SI: stretch [N/m], bend [N m], density [kg/m²]."""

    def __init__(
        self,
        mesh: GarmentMesh,
        *,
        stretch: float = 100.0,
        bend: float = 1e-5,
        density: float = 0.1,
        gravity=(0.0, 0.0, -9.81),
        seam_stiffness: float | None = None,
        body: SphereBody | None = None,
        contact_stiffness: float = 1e4,
        contact_offset: float = 0.005,
    ):
        self.mesh = mesh
        X = mesh.X
        tris = mesh.tris
        n = len(X)
        self.n = n
        self.stretch = stretch
        self.bend = bend
        self.density = density
        self.body = body
        self.contact_stiffness = contact_stiffness
        self.contact_offset = contact_offset
        area = 0.5 * np.abs(np.cross(X[tris[:, 1]] - X[tris[:, 0]], X[tris[:, 2]] - X[tris[:, 0]]))
        self.tri_area = area
        self.mass = np.zeros(n)
        np.add.at(self.mass, tris.ravel(), np.repeat(area / 3.0 * density, 3))
        self.mass = np.maximum(self.mass, 1e-12)
        self.free = np.ones(n, bool)
        self.free[mesh.pinned] = False
        self.pin_x = mesh.x0.copy()
        self.g = np.asarray(gravity, np.float64)
        self.f_gravity = self.mass[:, None] * self.g[None, :]

        edges, hinges = _edges_and_hinges(tris)
        self.edges = edges
        self.rest = np.linalg.norm(X[edges[:, 1]] - X[edges[:, 0]], axis=1)
        # spring stiffness so a uniformly stretched patch has roughly the membrane stiffness
        edge_area = np.zeros(len(edges))
        ekey = {(int(a), int(b)): k for k, (a, b) in enumerate(edges)}
        for t, tri in enumerate(tris):
            for a, b in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])):
                edge_area[ekey[(min(a, b), max(a, b))]] += area[t] / 3.0
        self.k_edge = stretch * edge_area / np.maximum(self.rest, 1e-12) ** 2 * 2.0

        # Bergou isometric bending: constant Hessian
        rows, cols, vals = [], [], []
        if len(hinges) and bend > 0:
            x0_, x1_, x2_, x3_ = (X[hinges[:, i]] for i in range(4))
            e0, e1, e2, e3, e4 = x1_ - x0_, x2_ - x0_, x3_ - x0_, x2_ - x1_, x3_ - x1_
            c01, c02 = _cot(e0, e1), _cot(e0, e2)
            c03, c04 = _cot(-e0, e3), _cot(-e0, e4)
            K = np.column_stack([c03 + c04, c01 + c02, -c01 - c03, -c02 - c04])
            a_sum = area[hinges[:, 4]] + area[hinges[:, 5]]
            w = 3.0 / a_sum * bend
            for i in range(4):
                for j in range(4):
                    rows.append(hinges[:, i])
                    cols.append(hinges[:, j])
                    vals.append(w * K[:, i] * K[:, j])
            Qs = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)).tocsr()
        else:
            Qs = sp.csr_matrix((n, n))
        self.Q = sp.kron(Qs, sp.eye(3), format="csr")

        # seams: emitter e tied to (1-w) x_a + w x_b
        self.seam_e = mesh.seam_emitters.astype(np.int64)
        self.seam_ab = mesh.seam_edges.astype(np.int64)
        self.seam_w = mesh.seam_weights
        if seam_stiffness is None:
            seam_stiffness = 5000.0 * stretch
        self.seam_k = seam_stiffness

        self._build_pattern()

    # ---- sparsity pattern, fixed for the model's lifetime ----
    def _build_pattern(self):
        n = self.n
        pairs = [np.column_stack([np.arange(n), np.arange(n)]), self.edges, self.edges[:, ::-1]]
        if len(self.seam_e):
            s3 = np.column_stack([self.seam_e, self.seam_ab])
            for i in range(3):
                for j in range(3):
                    pairs.append(s3[:, [i, j]])
        Qc = self.Q.tocoo()
        pairs.append(np.column_stack([Qc.row // 3, Qc.col // 3]))
        P = np.unique(np.concatenate(pairs), axis=0)
        R = np.repeat(3 * P[:, 0], 9) + np.tile(np.repeat(np.arange(3), 3), len(P))
        C = np.repeat(3 * P[:, 1], 9) + np.tile(np.tile(np.arange(3), 3), len(P))
        self._pattern = sp.csr_matrix((np.ones(len(R)), (R, C)), shape=(3 * n, 3 * n))
        self._pattern.sort_indices()
        self._pattern_coo = self._pattern.tocoo()
        self._Qcoo = self.Q.tocoo()

    # ---- contract ----
    def _seam_points(self, x):
        w = self.seam_w[:, None]
        return x[self.seam_e] - ((1 - w) * x[self.seam_ab[:, 0]] + w * x[self.seam_ab[:, 1]])

    def energy(self, x: np.ndarray) -> float:
        d = x[self.edges[:, 1]] - x[self.edges[:, 0]]
        l = np.linalg.norm(d, axis=1)
        E = 0.5 * np.sum(self.k_edge * (l - self.rest) ** 2)
        xf = x.ravel()
        E += 0.5 * xf @ (self.Q @ xf)
        E -= np.sum(self.f_gravity * x)
        if len(self.seam_e):
            E += 0.5 * self.seam_k * np.sum(self._seam_points(x) ** 2)
        if self.body is not None:
            phi, _ = self.body.phi_grad(x)
            pen = np.minimum(phi - self.contact_offset, 0.0)
            E += 0.5 * self.contact_stiffness * np.sum(pen**2)
        return float(E)

    def forces(self, x: np.ndarray) -> np.ndarray:
        n = self.n
        d = x[self.edges[:, 1]] - x[self.edges[:, 0]]
        l = np.linalg.norm(d, axis=1)
        fe = (self.k_edge * (l - self.rest) / np.maximum(l, 1e-300))[:, None] * d
        f = self.f_gravity.copy()
        np.add.at(f, self.edges[:, 0], fe)
        np.add.at(f, self.edges[:, 1], -fe)
        f -= (self.Q @ x.ravel()).reshape(n, 3)
        if len(self.seam_e):
            s = self.seam_k * self._seam_points(x)
            w = self.seam_w[:, None]
            np.add.at(f, self.seam_e, -s)
            np.add.at(f, self.seam_ab[:, 0], (1 - w) * s)
            np.add.at(f, self.seam_ab[:, 1], w * s)
        if self.body is not None:
            phi, g = self.body.phi_grad(x)
            pen = np.minimum(phi - self.contact_offset, 0.0)
            f -= (self.contact_stiffness * pen)[:, None] * g
        return f

    def stiffness(self, x: np.ndarray) -> sp.csr_matrix:
        n = self.n
        d = x[self.edges[:, 1]] - x[self.edges[:, 0]]
        l = np.maximum(np.linalg.norm(d, axis=1), 1e-300)
        u = d / l[:, None]
        a = self.k_edge
        b = self.k_edge * np.maximum(1.0 - self.rest / l, 0.0)  # PSD projection under compression
        H = a[:, None, None] * u[:, :, None] * u[:, None, :] + b[:, None, None] * (np.eye(3) - u[:, :, None] * u[:, None, :])
        i, j = self.edges[:, 0], self.edges[:, 1]
        blocks_r = [i, j, i, j]
        blocks_c = [i, j, j, i]
        signs = [1, 1, -1, -1]
        R, C, V = [], [], []
        for br, bc, s in zip(blocks_r, blocks_c, signs):
            R.append(np.repeat(3 * br, 9) + np.tile(np.repeat(np.arange(3), 3), len(br)))
            C.append(np.repeat(3 * bc, 9) + np.tile(np.tile(np.arange(3), 3), len(bc)))
            V.append((s * H).ravel())
        if len(self.seam_e):
            w = self.seam_w
            coef = np.column_stack([np.ones_like(w), -(1 - w), -w])
            s3 = np.column_stack([self.seam_e, self.seam_ab])
            for p in range(3):
                for q in range(3):
                    c = self.seam_k * coef[:, p] * coef[:, q]
                    for k in range(3):
                        R.append(3 * s3[:, p] + k)
                        C.append(3 * s3[:, q] + k)
                        V.append(c)
        if self.body is not None:
            phi, g = self.body.phi_grad(x)
            act = phi - self.contact_offset < 0
            idx = np.nonzero(act)[0]
            gg = g[idx]
            Hc = self.contact_stiffness * gg[:, :, None] * gg[:, None, :]
            R.append(np.repeat(3 * idx, 9) + np.tile(np.repeat(np.arange(3), 3), len(idx)))
            C.append(np.repeat(3 * idx, 9) + np.tile(np.tile(np.arange(3), 3), len(idx)))
            V.append(Hc.ravel())
        Qc = self._Qcoo
        pc = self._pattern_coo
        R += [Qc.row, pc.row]
        C += [Qc.col, pc.col]
        V += [Qc.data, np.zeros(len(pc.row))]
        # duplicates summed, explicit zeros kept: the same sparsity every call
        out = sp.coo_matrix((np.concatenate(V), (np.concatenate(R), np.concatenate(C))), shape=(3 * n, 3 * n)).tocsr()
        out.sort_indices()
        if out.nnz != self._pattern.nnz:  # pragma: no cover - pattern covers everything
            raise RuntimeError("stiffness pattern changed")
        return out

    def relative_residual(self, x: np.ndarray) -> float:
        f = self.forces(x)
        num = np.linalg.norm(f[self.free])
        den = np.linalg.norm(self.f_gravity)
        if den == 0:
            den = max(np.linalg.norm(f - self.f_gravity), 1e-12)
        return float(num / den)

    def update_friction(self, x: np.ndarray) -> None:
        return None


def hanging_sheet(nx: int = 12, ny: int = 12, size: float = 0.5, *, model_cls=SpringSheetModel, **kw):
    """A horizontal square sheet at z = 0 pinned at its two corners y = size."""
    from couture.mesh import grid_sheet

    m = grid_sheet(size, size, nx, ny)
    X = m.X
    top = np.nonzero(np.isclose(X[:, 1], size))[0]
    corners = top[[np.argmin(X[top, 0]), np.argmax(X[top, 0])]]
    m.pinned = corners.astype(np.int32)
    return model_cls(m, **kw)


# --------------------------------------------------------------------------
# scenes on the real couture.cloth.ClothModel
# --------------------------------------------------------------------------


def fabric(stretch: float = 500.0, bend: float = 1e-6, density: float = 0.15, poisson: float = 0.3):
    """A fabric record with the fields ClothModel reads (SC Table 1 ranges)."""
    try:  # the shared Fabric type, once it exists
        from couture.cloth import Fabric  # type: ignore[attr-defined]

        return Fabric(stretch_stiffness=stretch, bend_stiffness=bend, area_density=density, poisson_ratio=poisson)
    except Exception:
        from types import SimpleNamespace

        return SimpleNamespace(stretch_stiffness=stretch, bend_stiffness=bend, area_density=density,
                               poisson_ratio=poisson, friction_static=0.5, friction_kinetic=0.3)


def horizontal(mesh: GarmentMesh, height: float = 0.0, center=None) -> GarmentMesh:
    """Place the pattern flat in the x-z plane (y up, the cloth model's gravity axis) at y = height."""
    X = mesh.X
    c = X.mean(axis=0) if center is None else np.asarray(center, float)
    mesh.x0 = np.column_stack([X[:, 0] - c[0], np.full(len(X), height), X[:, 1] - c[1]])
    return mesh


def cloth_hanging_sheet(nx: int = 12, ny: int = 12, size: float = 0.5, *, fab=None, scene=None) -> "object":
    """Real ClothModel: a horizontal square sheet pinned at the two corners of one edge."""
    from couture.cloth import ClothModel, Scene
    from couture.mesh import grid_sheet

    m = horizontal(grid_sheet(size, size, nx, ny), center=(size / 2, size / 2))
    X = m.X
    top = np.nonzero(np.isclose(X[:, 1], size))[0]
    m.pinned = top[[np.argmin(X[top, 0]), np.argmax(X[top, 0])]].astype(np.int32)
    return ClothModel(m, fab or fabric(), scene or Scene())


def cloth_edge_pinned_sheet(nx: int, ny: int, size: float = 0.5, *, fab=None, scene=None):
    """Real ClothModel: a horizontal sheet clamped along its whole edge y = size (cantilever/curtain)."""
    from couture.cloth import ClothModel, Scene
    from couture.mesh import grid_sheet

    m = horizontal(grid_sheet(size, size, nx, ny), center=(size / 2, size / 2))
    m.pinned = np.nonzero(np.isclose(m.X[:, 1], size))[0].astype(np.int32)
    return ClothModel(m, fab or fabric(), scene or Scene())


def cloth_sphere_drape(nx: int = 16, *, fab=None, size: float = 0.6, radius: float = 0.2, friction: bool = False):
    """SC Fig. 5 scene: a square cloth pinned along one edge, partly draped on a sphere.

    Sphere of radius 0.2 m at the origin; the 0.6 m cloth starts flat 2 cm above
    the sphere's top, its pinned edge over the sphere, 5 cm before its centre,
    so the rest of it falls over the sphere and hangs on the far side.

    (The pinned edge used to be 0.15 m *outside* the sphere's footprint: without
    friction the cloth then slides off and hangs free from its pins, 25 cm from
    the sphere, with every solver; re-run, the drape never touched the sphere.)
    """
    from couture.cloth import ClothModel, Scene
    from couture.cloth.body import SphereBody as Sphere
    from couture.mesh import grid_sheet

    m = grid_sheet(size, size, nx, nx)
    X = m.X
    m.x0 = np.column_stack([X[:, 0] - size / 2, np.full(len(X), radius + 0.02), X[:, 1] - 0.05])
    m.pinned = np.nonzero(np.isclose(X[:, 1], 0.0))[0].astype(np.int32)
    body = Sphere(center=np.zeros(3), radius=radius)
    return ClothModel(m, fab or fabric(), Scene(body=body, friction=friction))
