"""Hand-built drafted patterns for the remesher's tests and benchmark fallback:
rectangles, an L with a hole, a U, two panels sewn with unequal lengths, a
boundary dart (a notch whose legs are sewn), and a four-panel tube.
Dimensions in metres; outlines counter-clockwise, holes clockwise."""

from __future__ import annotations

import numpy as np

from couture.pattern.drafted import DraftedPattern, Panel, SeamSpec, Segment


def polyline(corners: np.ndarray, per_edge: int | list[int]) -> tuple[np.ndarray, list[int]]:
    """Closed polyline through ``corners`` with ``per_edge`` points per edge
    (int or one per edge); returns (points (k, 2), index of each corner)."""
    corners = np.asarray(corners, np.float64)
    c = len(corners)
    counts = [int(per_edge)] * c if isinstance(per_edge, (int, np.integer)) else list(per_edge)
    pts: list[np.ndarray] = []
    idx: list[int] = []
    for i in range(c):
        idx.append(sum(len(p) for p in pts))
        t = np.arange(counts[i])[:, None] / counts[i]
        pts.append(corners[i] + t * (corners[(i + 1) % c] - corners[i]))
    return np.concatenate(pts), idx


def rect_corners(w: float, h: float, x0: float = 0.0, y0: float = 0.0) -> np.ndarray:
    return np.array([[x0, y0], [x0 + w, y0], [x0 + w, y0 + h], [x0, y0 + h]], np.float64)


def rectangle_panel(name: str, w: float, h: float, per_edge=20, *, x0: float = 0.0, y0: float = 0.0) -> Panel:
    """Rectangle with segments 'bottom', 'right', 'top', 'left'."""
    P, c = polyline(rect_corners(w, h, x0, y0), per_edge)
    k = len(P)
    segs = [
        Segment(nm, c[i], c[(i + 1) % 4] if i < 3 else 0) for i, nm in enumerate(["bottom", "right", "top", "left"])
    ]
    del k
    return Panel(name, P, segments=segs)


def l_corners(arm: float = 0.3, size: float = 1.0) -> np.ndarray:
    return np.array([[0, 0], [size, 0], [size, arm], [arm, arm], [arm, size], [0, size]], np.float64)


def l_panel(name: str = "L", per_edge: int = 16, *, hole: bool = True) -> Panel:
    """An L (arms 0.3 m wide, 1 m long), optionally with a square hole in its corner block."""
    P, _ = polyline(l_corners(), per_edge)
    holes = []
    if hole:
        H, _ = polyline(rect_corners(0.12, 0.12, 0.09, 0.09), 6)
        holes = [H[::-1].copy()]
    return Panel(name, P, holes=holes)


def u_panel(name: str = "U", per_edge: int = 16, *, hole: bool = True) -> Panel:
    """A U: base 1 x 0.3 m, two arms 0.3 m wide rising to 1 m; optional hole in the base."""
    C = np.array([[0, 0], [1, 0], [1, 1], [0.7, 1], [0.7, 0.3], [0.3, 0.3], [0.3, 1], [0, 1]], np.float64)
    P, _ = polyline(C, per_edge)
    holes = []
    if hole:
        H, _ = polyline(rect_corners(0.2, 0.1, 0.4, 0.1), 8)
        holes = [H[::-1].copy()]
    return Panel(name, P, holes=holes)


def sewn_pair(len_a: float = 0.6, len_b: float = 0.9, per_edge_a: int = 12, per_edge_b: int = 30) -> DraftedPattern:
    """Two rectangles sewn along a's right edge and b's left edge; b's edge is
    longer (a gather) and has more polyline vertices."""
    a = rectangle_panel("a", 0.5, len_a, per_edge_a)
    b = rectangle_panel("b", 0.5, len_b, per_edge_b, x0=0.7)
    return DraftedPattern([a, b], [SeamSpec("a", "right", "b", "left", reverse=True)])


def dart_panel(name: str = "dart", per_edge: int = 20) -> DraftedPattern:
    """A 0.6 x 0.5 m panel with a boundary dart: a V notch cut into the top
    edge whose two legs are sewn to each other (SeamSpec on the same panel)."""
    C = np.array([[0, 0], [0.6, 0], [0.6, 0.5], [0.34, 0.5], [0.3, 0.3], [0.26, 0.5], [0, 0.5]], np.float64)
    counts = [per_edge, per_edge, per_edge // 2, per_edge // 2, per_edge // 2, per_edge // 2, per_edge]
    P, c = polyline(C, counts)
    segs = [Segment("leg_in", c[3], c[4]), Segment("leg_out", c[4], c[5])]
    panel = Panel(name, P, segments=segs)
    # leg_in runs notch edge -> tip, leg_out tip -> other notch edge: sew them tip to tip
    return DraftedPattern([panel], [SeamSpec(name, "leg_in", name, "leg_out", reverse=True)])


def tube(n_panels: int = 4, width: float = 0.45, height: float = 0.7, per_edge: int = 60) -> DraftedPattern:
    """A skirt-like tube: n rectangles side by side, each sewn right-to-left to the next."""
    panels = [rectangle_panel(f"p{i}", width, height, per_edge, x0=i * (width + 0.1)) for i in range(n_panels)]
    seams = [SeamSpec(f"p{i}", "right", f"p{(i + 1) % n_panels}", "left") for i in range(n_panels)]
    return DraftedPattern(panels, seams)
