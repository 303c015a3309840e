"""Small helpers shared by the UI's panels."""

from __future__ import annotations

import math
import threading
import time
from typing import Any, Callable

import numpy as np


def on_user_change(handle: Any, fn: Callable[[], None]) -> None:
    """Run ``fn`` when the designer changes ``handle`` in a browser.

    viser runs a handle's update callbacks also when the code assigns its
    value, with ``event.client`` None; such a write mirrors state the UI
    already holds (a design from the bus, a preset's numbers) and must not
    be sent back out as a user action.
    """
    handle.on_update(lambda event: None if event.client is None else fn())


def nice_step(span: float) -> float:
    """A slider step of about span / 200, rounded down to a power of ten."""
    if span <= 0:
        return 0.01
    return float(10 ** math.floor(math.log10(span / 200.0)))


Fit = Callable[[float], tuple[tuple[float, float, float], tuple[float, float, float]]]
"""aspect (width / height) -> camera (position, look_at) [m]"""


class ClientFraming:
    """Frames each browser's camera to its own canvas: once the client has
    reported its viewport, and again when the viewport's shape changes while
    the designer has not moved the camera since it was framed."""

    def __init__(self, server: Any, fit: Fit):
        self.server, self.fit = server, fit
        self._applied: dict[int, tuple[float, list[np.ndarray]]] = {}
        """client id -> (aspect last framed for, camera positions set here)"""
        self._lock = threading.Lock()
        server.on_client_connect(self._connect)

    def _connect(self, client: Any) -> None:
        client.camera.on_update(lambda cam: self._camera_moved(client, cam))
        # a client may have reported its viewport before this callback was
        # attached, and reports again only when its camera changes
        threading.Thread(target=self._first_frame, args=(client,), name="couture-frame-client", daemon=True).start()

    def _first_frame(self, client: Any, timeout: float = 60.0) -> None:
        t0 = time.monotonic()
        while time.monotonic() - t0 < timeout:
            with self._lock:
                if client.client_id in self._applied:
                    return
            try:
                if client.camera.image_width > 0:
                    self.apply(client)
                    return
            except Exception:  # viewport not reported yet, or the client left
                pass
            time.sleep(0.05)

    def _camera_moved(self, client: Any, cam: Any) -> None:
        if cam.image_width <= 0 or cam.image_height <= 0:
            return
        aspect = cam.image_width / cam.image_height
        with self._lock:
            last = self._applied.get(client.client_id)
        if last is not None:
            if abs(aspect / last[0] - 1.0) < 0.02:
                return
            # a report may predate what was set here (it crossed on the way):
            # the designer moved the camera only if it is at none of those places
            ours = [*last[1], np.asarray(self.server.initial_camera.position, np.float64)]
            p = np.asarray(cam.position, np.float64)
            if all(np.linalg.norm(p - q) > 1e-3 * max(float(np.linalg.norm(q)), 1.0) for q in ours):
                return
        self.apply(client)

    def apply(self, client: Any) -> None:
        cam = client.camera
        if cam.image_width <= 0 or cam.image_height <= 0:
            return
        aspect = cam.image_width / cam.image_height
        position, look_at = self.fit(aspect)
        with self._lock:
            placed = self._applied.get(client.client_id, (aspect, []))[1]
            self._applied[client.client_id] = (aspect, [*placed[-7:], np.asarray(position, np.float64)])
        with client.atomic():
            cam.up_direction = (0.0, 1.0, 0.0)
            cam.position = position  # moves look_at along: set it after
            cam.look_at = look_at

    def reframe(self) -> None:
        """Frame every connected client now (the content changed)."""
        for client in list(self.server.get_clients().values()):
            try:
                self.apply(client)
            except Exception:  # a client that left meanwhile
                pass


def fit_distance(half_width: float, half_height: float, fov: float, aspect: float, fill: float = 0.9) -> float:
    """Camera distance [m] at which a box of the given half extents [m], seen
    face on with vertical field of view ``fov`` [rad], spans ``fill`` of the
    canvas in its tighter direction."""
    t = math.tan(0.5 * fov) * fill
    return max(half_height / t, half_width / (t * max(aspect, 1e-3)))
