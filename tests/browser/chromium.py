"""Headless Debian chromium for UI tests and the UI benchmark (never a
downloaded browser: no ``playwright install``)."""

from __future__ import annotations

import contextlib
import shutil
import tempfile
import time
from pathlib import Path
from typing import Callable, Iterator

CHROMIUM = "/usr/bin/chromium"
ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
ARTIFACTS = Path(__file__).resolve().parents[2] / "test-artifacts"


def available() -> bool:
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return False
    return shutil.which(CHROMIUM) is not None or Path(CHROMIUM).exists()


@contextlib.contextmanager
def browser_page(width: int = 1400, height: int = 800) -> Iterator[object]:
    """A page in a fresh headless chromium with its own user-data-dir."""
    from playwright.sync_api import sync_playwright

    profile = tempfile.mkdtemp(prefix="couture-chromium-")
    try:
        with sync_playwright() as p:
            ctx = p.chromium.launch_persistent_context(
                profile,
                executable_path=CHROMIUM,
                args=ARGS,
                headless=True,
                viewport={"width": width, "height": height},
                accept_downloads=True,
            )
            try:
                page = ctx.pages[0] if ctx.pages else ctx.new_page()
                yield page
            finally:
                ctx.close()
    finally:
        shutil.rmtree(profile, ignore_errors=True)


def wait_until(cond: Callable[[], object], timeout: float = 60.0, page=None, step_ms: int = 100) -> object:
    """Poll cond() (server-side state) until truthy; pumps the page's event
    loop while waiting so playwright events keep flowing."""
    t0 = time.time()
    while time.time() - t0 < timeout:
        v = cond()
        if v:
            return v
        if page is not None:
            page.wait_for_timeout(step_ms)
        else:
            time.sleep(step_ms / 1000)
    raise TimeoutError(f"condition not met within {timeout} s")


def wait_camera(server, timeout: float = 60.0, page=None):
    """The first connected client of a viser server once its camera is known."""

    def ready():
        for c in server.get_clients().values():
            try:
                cam = c.camera
                if cam.image_width > 0:
                    return c
            except Exception:
                pass
        return None

    return wait_until(ready, timeout, page)


def stable_camera(client, page=None, settle_s: float = 1.0, timeout: float = 30.0):
    """The client's camera once it has stopped changing for ``settle_s`` (under
    load the page may still be resizing its canvas after it first reports)."""
    import numpy as np

    def snap():
        c = client.camera
        return np.concatenate(
            [
                np.asarray(c.position, float),
                np.asarray(c.wxyz, float),
                [float(c.fov), float(c.image_width), float(c.image_height)],
            ]
        )

    t0 = time.time()
    last, since = snap(), time.time()
    while time.time() - t0 < timeout:
        if page is not None:
            page.wait_for_timeout(100)
        else:
            time.sleep(0.1)
        now = snap()
        if not np.allclose(now, last, rtol=0, atol=1e-9):
            last, since = now, time.time()
        elif time.time() - since >= settle_s:
            return client.camera
    raise TimeoutError("the browser camera kept changing")
