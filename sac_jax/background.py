"""Work off the training's critical path: writes that run in order on one background thread,
the lock that keeps apart the imports made on several threads, and the gate that keeps those
imports out of the host loop's work between chunks."""

from __future__ import annotations

import builtins
import concurrent.futures
import contextlib
import sys
import threading
import time

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


MAX_IMPORT_HOLD_S = 0.05
"""How long, at most, `LoopImportGate` holds imports back in each spell of the host loop's work
between chunks: the loop's work takes about 3 ms a chunk for one seed on an H100's host and
12 ms for 256, and a loop that works longer (a follower waiting for a write, or for a module
another thread is loading) lets them go on."""


class LoopImportGate:
    """While installed (`with`), an import statement on a thread other than the one that
    installed it (the host loop's) that would load a module not loaded yet waits while the
    loop works between chunks: until the loop is `waiting()` for the device again, or at most
    `MAX_IMPORT_HOLD_S` after its work began. It waits in `builtins.__import__`, before the
    import machinery takes any lock (a `sys.meta_path` finder is called holding the
    interpreter's global import lock, which every thread's imports, the loop's too, would then
    wait for).

    The scripts import orbax on a thread while a warm run starts (and, until
    `sac_jax.records_process`, TensorBoard's writer and matplotlib), and on a GPU those imports
    outlasted the cached programs' loading by about a second.
    Each module they load holds the GIL, so the loop's work between two chunks (fetching the
    point, calling the followers, dispatching the next chunk) waited for them while the device
    had nothing to do. rejax's Pendulum-v1 SAC, 1 seed, 19 chunks of about 90 ms on an H100
    (2026-12-07, 4 warm runs each): the first 4-5 chunks took 95-202 ms and training
    1.90-1.99 s, against 1.76-1.77 s with those imports done before the script started. With
    the gate, on another H100: 1.845-1.870 s against 1.877-1.923 s (4 alternated rounds); the
    bodies of modules already begun still take their share (the collector's passes do not:
    docs/performance.md)."""

    def __init__(self):
        self._loop = threading.get_ident()
        self._waiting = threading.Event()  # set while the loop waits, and once the gate is gone
        self._held_until = 0.0  # `time.perf_counter()` at which this spell's hold ends
        self._import = builtins.__import__

    def _gated_import(self, name, globals=None, locals=None, fromlist=(), level=0):
        if threading.get_ident() != self._loop and (level or name not in sys.modules):
            hold = self._held_until - time.perf_counter()
            if hold > 0:
                self._waiting.wait(hold)
        return self._import(name, globals, locals, fromlist, level)

    def _work(self) -> None:
        self._held_until = time.perf_counter() + MAX_IMPORT_HOLD_S
        self._waiting.clear()

    def __enter__(self) -> "LoopImportGate":
        self._work()
        builtins.__import__ = self._gated_import
        return self

    def __exit__(self, *error) -> None:
        self._held_until = 0.0
        self._waiting.set()
        builtins.__import__ = self._import

    @contextlib.contextmanager
    def waiting(self):
        """Lets the held imports run while the block waits for the device."""
        self._held_until = 0.0
        self._waiting.set()
        try:
            yield
        finally:
            self._work()
