"""Work off the training's critical path: writes that run in order on one background thread,
and the lock that keeps apart the imports made on several threads."""

from __future__ import annotations

import concurrent.futures
import threading

SYNTAX_TREE_IMPORTS = threading.Lock()
"""Held by whichever thread imports (or starts) a library that builds Python syntax trees as it
loads: wandb (pydantic reads its models' field docstrings with `ast.parse`, at `import wandb` and
in `wandb.init`) and matplotlib (its rc validators call `ast.literal_eval`). CPython 3.11 keeps
the tree constructor's recursion count once per interpreter, not per thread, so two threads
building trees at once can fail with SystemError "AST constructor recursion depth mismatch"
(two threads parsing for 8 s: 3.11.7 failed within them, 3.12.1 and 3.13.0 never did). CI met it
as W&B started on its thread while matplotlib was imported on another."""


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


