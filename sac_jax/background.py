"""Writes that run off the training's critical path, in order, on one background thread."""

from __future__ import annotations

import concurrent.futures


class BackgroundWrites:
    """Writes run in order on one background thread. A failed write is re-raised by the next
    `submit` or by `close()`, which waits for them all."""

    def __init__(self):
        self._pool = concurrent.futures.ThreadPoolExecutor(1)
        self._writes: list = []

    def _collect(self, wait: bool) -> None:
        """Drops the finished writes (all, after waiting, if `wait`), re-raising a failure."""
        finished = self._writes if wait else [w for w in self._writes if w.done()]
        self._writes = [w for w in self._writes if w not in finished]
        for write in finished:
            write.result()

    def submit(self, write, *args) -> None:
        self._collect(wait=False)
        self._writes.append(self._pool.submit(write, *args))

    def close(self) -> None:
        try:
            self._collect(wait=True)
        finally:
            self._pool.shutdown()


