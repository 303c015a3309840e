"""Direct 3D editing (SC §4.1): a drag of a picked cloth point in the 3D view
becomes a change of sloper parameter(s) g.

s = ∂x/∂g at the picked point (3,) or (3, k) for k active parameters is mapped
to screen space by the Jacobian of the projection at the picked point x:
ŝ = J s [px per unit of g]. Then

- one parameter: Δg = ŝ·Δd / |ŝ|²
- k parameters: Δg = argmin |Ŝ Δg - Δd|² (pseudo-inverse, dropping directions
  whose singular value is below the threshold)

Drags at points with |ŝ| below ``min_px_per_unit`` are neglected (SC: "for
small |ŝ| we neglect the drag"): Δg = 0 and ``ignored`` is set.

Screen convention: pixels, origin top-left, y down; ``view_proj`` maps world
(column vector, homogeneous) to clip space, OpenGL style (NDC in [-1, 1]).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class DragResult:
    dg: np.ndarray
    """parameter change (k,) [units of g]"""
    ignored: bool
    """True when the picked point is insensitive to g (drag neglected)"""
    s_screen: np.ndarray
    """ŝ (2, k) [px per unit of g]"""


def project_jacobian(view_proj: np.ndarray, viewport, x_point: np.ndarray) -> np.ndarray:
    """J (2, 3) [px/m]: derivative of the pixel position of a world point at x_point."""
    P = np.asarray(view_proj, dtype=np.float64)
    w, h = float(viewport[0]), float(viewport[1])
    xh = np.append(np.asarray(x_point, dtype=np.float64), 1.0)
    c = P @ xh
    cw = c[3]
    dndc = (P[:2, :3] * cw - np.outer(c[:2], P[3, :3])) / (cw * cw)
    return np.diag([0.5 * w, -0.5 * h]) @ dndc


def drag_to_param(s_point, view_proj, viewport, x_point, drag_px, *, min_px_per_unit: float = 1.0) -> DragResult:
    """Parameter change for a pointer drag of ``drag_px`` (2,) [px] at a picked
    cloth point x_point (3,) [m] whose sensitivity is s_point (3,) or (3, k)
    [m per unit of g]. See the module docstring."""
    s = np.asarray(s_point, dtype=np.float64)
    s = s.reshape(3, -1)
    J = project_jacobian(view_proj, viewport, x_point)
    sh = J @ s
    dd = np.asarray(drag_px, dtype=np.float64).reshape(2)
    k = s.shape[1]
    if k == 1:
        n2 = float(sh[:, 0] @ sh[:, 0])
        if np.sqrt(n2) < min_px_per_unit:
            return DragResult(np.zeros(1), True, sh)
        return DragResult(np.array([sh[:, 0] @ dd / n2]), False, sh)
    U, sv, Vt = np.linalg.svd(sh, full_matrices=False)
    ok = sv >= min_px_per_unit
    if not np.any(ok):
        return DragResult(np.zeros(k), True, sh)
    dg = Vt[ok].T @ ((U[:, ok].T @ dd) / sv[ok])
    return DragResult(dg, False, sh)
