"""The lifecycle every node shares: open the bus, declare liveliness, publish
``status/<node>`` periodically, run until SIGINT/SIGTERM, close everything.

    def main(config: Config) -> None:
        with Node("solver", config.bus, kind="solver") as node:
            drape_pub = node.bus.publisher("drape/fine", DrapeMsg)
            node.bus.subscribe("mesh/*", on_mesh)
            node.run()                      # returns on SIGINT/SIGTERM or node.stop()
"""

from __future__ import annotations

import logging
import os
import signal
import threading
import time
from typing import Any, Callable, Protocol

from couture.bus.session import Bus, BusConfig, open_session
from schemas.messages import StatusMsg

log = logging.getLogger("couture.node")

PARENT_PID_ENV = "COUTURE_PARENT_PID"
"""set by the supervisor: a child whose parent dies stops instead of lingering as an orphan"""


class StopFlag:
    """SIGINT/SIGTERM -> a threading.Event; a second signal raises KeyboardInterrupt.

    Installing it in the main thread makes SIGTERM end ``Node.run()`` (and any
    loop that polls the flag) so ``finally`` blocks close the Zenoh session;
    atexit would run too late (after Zenoh's threads hang the interpreter).
    """

    def __init__(self) -> None:
        self.event = threading.Event()
        self.signum: int | None = None
        self._previous: dict[int, object] = {}

    def install(self) -> "StopFlag":
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def restore(self) -> None:
        for sig, prev in self._previous.items():
            signal.signal(sig, prev)  # type: ignore[arg-type]
        self._previous.clear()

    def _handle(self, signum: int, frame: object) -> None:
        if self.event.is_set():
            raise KeyboardInterrupt
        self.signum = signum
        self.event.set()

    def is_set(self) -> bool:
        return self.event.is_set()

    def wait(self, timeout: float | None = None) -> bool:
        return self.event.wait(timeout)

    def set(self) -> None:
        self.event.set()


class Readiness(Protocol):
    """What a node's status reports as ready (see :class:`StatusMsg`)."""

    @property
    def ready(self) -> bool: ...
    @property
    def generation(self) -> int: ...
    @property
    def mesh_generation(self) -> int: ...


class Node:
    """A bus participant with presence and status. Context manager."""

    def __init__(
        self,
        name: str,
        bus_config: BusConfig,
        *,
        kind: str = "",
        status_period_s: float = 1.0,
        install_signals: bool = True,
        announce: bool = True,
    ) -> None:
        self.name = name
        self.kind = kind or name
        self.cfg = bus_config
        self.status_period_s = status_period_s
        self.state = "starting"
        self.stop_flag = StopFlag()
        self._install_signals = install_signals
        self._announce = announce
        self._t0 = time.monotonic()
        self._bus: Bus | None = None
        self._status_thread: threading.Thread | None = None
        self.readiness: Callable[[], Readiness] | None = None
        """what the status reports as ready: returns an object with ``ready``,
        ``generation`` and ``mesh_generation`` (None: always ready)"""
        self.status_fields: Callable[[], dict[str, Any]] | None = None
        """more :class:`StatusMsg` fields this node fills (the ui: ``nodes``, ``shown``)"""

    @property
    def bus(self) -> Bus:
        """The open session, between ``__enter__`` and ``__exit__``."""
        if self._bus is None:
            raise RuntimeError(f"{type(self).__name__} {self.name!r} is not open: use it in a `with` block")
        return self._bus

    def announce(self) -> None:
        """Declare the liveliness token now (for a node built with
        ``announce=False`` that must subscribe before it is seen as live)."""
        self.bus.declare_token(self.name)

    # -- stats shortcuts
    def count(self, name: str, n: int = 1) -> None:
        """Add to a counter (also reported as a rate in the status message)."""
        self.bus.stats.count(name, n)

    def error(self, text: str) -> None:
        """Record the last error (published in the status message)."""
        log.error("%s: %s", self.name, text)
        self.bus.stats.error(text)

    # -- lifecycle
    def __enter__(self) -> "Node":
        if self._install_signals:
            self.stop_flag.install()
        self._bus = open_session(self.cfg, name=self.name)
        try:
            self._status_pub = self.bus.publisher(f"status/{self.name}", StatusMsg)
            if self._announce:
                self.bus.declare_token(self.name)
            self.state = "running"
            self._status_thread = threading.Thread(target=self._status_loop, name="status", daemon=True)
            self._status_thread.start()
        except BaseException:
            self.bus.close()
            raise
        log.info("node %s up in session %s (pid %d)", self.name, self.cfg.session, os.getpid())
        return self

    def __exit__(self, *exc: object) -> None:
        self.state = "stopping"
        self.stop_flag.set()
        try:
            if self._status_thread is not None:
                self._status_thread.join(timeout=2.0)
            try:
                self.publish_status()
            except Exception:
                pass
        finally:
            self.bus.close()
            self.stop_flag.restore()
            log.info("node %s stopped", self.name)

    def run(self, idle: Callable[[], object] | None = None, period_s: float = 0.05) -> None:
        """Block until SIGINT/SIGTERM or stop(); call ``idle()`` every period_s."""
        while not self.stop_flag.wait(period_s):
            if idle is not None:
                try:
                    idle()
                except Exception as e:
                    self.bus.stats.count("callback_errors")
                    self.error(f"idle raised {type(e).__name__}: {e}")

    def stop(self) -> None:
        self.stop_flag.set()

    @property
    def stopping(self) -> bool:
        return self.stop_flag.is_set()

    def status(self) -> StatusMsg:
        st = self.bus.stats
        r = self.readiness() if self.readiness is not None else None
        return StatusMsg(
            node=self.name,
            kind=self.kind,
            pid=os.getpid(),
            state=self.state,
            uptime_s=time.monotonic() - self._t0,
            rates=st.take_rates(),
            counters=st.snapshot(),
            last_error=st.last_error,
            ready=True if r is None else bool(r.ready),
            ready_generation=-1 if r is None else int(r.generation),
            ready_mesh_generation=-1 if r is None else int(r.mesh_generation),
            regularization=str(getattr(r, "regularization", "")),
            **(self.status_fields() if self.status_fields is not None else {}),
        )

    def publish_status(self) -> None:
        self._status_pub.put(self.status())

    def _status_loop(self) -> None:
        parent = int(os.environ.get(PARENT_PID_ENV, "0") or 0)
        next_t = time.monotonic()
        while not self.stop_flag.is_set():
            if parent and os.getppid() != parent:
                log.warning("%s: supervisor (pid %d) is gone, stopping", self.name, parent)
                self.stop_flag.set()
                break
            if time.monotonic() >= next_t:
                try:
                    self.publish_status()
                except Exception as e:
                    log.warning("status publish failed: %s", e)
                next_t = time.monotonic() + self.status_period_s
            self.stop_flag.wait(0.1)
