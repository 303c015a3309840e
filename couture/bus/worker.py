"""Hand work from Zenoh callbacks to one worker thread, newest job wins per slot.

Bus callbacks must return quickly; nodes put jobs here and a single thread runs
them in order of arrival. Jobs in the same *slot* coalesce: if a newer pattern
arrives while an older one is still queued, only the newer one runs (the
older is counted as superseded). A job that raises is logged and counted by
the node; the worker keeps going.
"""

from __future__ import annotations

import logging
import threading
from collections import OrderedDict
from typing import Any, Callable

log = logging.getLogger(__name__)


class LatestWorker:
    def __init__(self, name: str, on_error: Callable[[str], Any] | None = None) -> None:
        self.name = name
        self._jobs: OrderedDict[str, Callable[[], Any]] = OrderedDict()
        self._cv = threading.Condition()
        self._stop = False
        self._on_error = on_error
        self.superseded = 0
        self.busy = False
        self._thread = threading.Thread(target=self._loop, name=name, daemon=True)
        self._thread.start()

    def submit(self, slot: str, job: Callable[[], Any]) -> None:
        """Queue ``job`` in ``slot``, replacing a queued job of the same slot."""
        with self._cv:
            if slot in self._jobs:
                self.superseded += 1
                del self._jobs[slot]
            self._jobs[slot] = job
            self._cv.notify()

    def pending(self, slot: str | None = None) -> bool:
        with self._cv:
            return bool(self._jobs) if slot is None else slot in self._jobs

    def _loop(self) -> None:
        while True:
            with self._cv:
                while not self._jobs and not self._stop:
                    self._cv.wait()
                if self._stop:
                    return
                _, job = self._jobs.popitem(last=False)
                self.busy = True
            try:
                job()
            except Exception as e:  # a failed job never kills the node
                log.exception("%s: job failed", self.name)
                if self._on_error is not None:
                    self._on_error(f"{type(e).__name__}: {e}")
            finally:
                self.busy = False

    def close(self, timeout: float = 5.0) -> None:
        with self._cv:
            self._stop = True
            self._jobs.clear()
            self._cv.notify_all()
        self._thread.join(timeout)
