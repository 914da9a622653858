"""W&B starting on its thread, matplotlib imported on `plots.prepare`'s thread and a figure made on
the main thread, all at once in a fresh process, with every `ast.parse` watched (ast.literal_eval
and inspect call it too): prints one JSON line with how many calls each thread made, how many
were made by a thread not holding `background.SYNTAX_TREE_IMPORTS`, and how many began while
another thread was inside one.

    python -m tests.concurrent_imports RUN_DIR      # with W&B offline (WANDB_MODE=offline)
"""

from __future__ import annotations

import ast
import collections
import json
import sys
import threading

from sac_jax import background, plots, tracking


class OwnedLock:
    """A lock that says which thread holds it."""

    def __init__(self):
        self._lock, self.owner = threading.Lock(), None

    def __enter__(self):
        self._lock.acquire()
        self.owner = threading.current_thread().name

    def __exit__(self, *exc_info):
        self.owner = None
        self._lock.release()


def main(run_dir: str) -> None:
    lock = background.SYNTAX_TREE_IMPORTS = OwnedLock()

    sys.setswitchinterval(1e-6)  # threads take turns as often as Python lets them
    parse, inside = ast.parse, set()
    calls, unguarded, overlapping = (collections.Counter() for _ in range(3))

    def watched(*args, **kwargs):
        me = threading.current_thread().name
        calls[me] += 1
        unguarded[me] += lock.owner != me
        overlapping[me] += bool(inside - {me})
        inside.add(me)
        try:
            return parse(*args, **kwargs)
        finally:
            inside.discard(me)

    ast.parse = watched
    tracked = tracking.settings("concurrent-imports", None, None, "offline")
    wandb_run = tracking.WandbRun(run_dir, tracked, {}, [])
    prepare = threading.Thread(target=plots.prepare, name="plots.prepare")
    prepare.start()
    plots.figure()
    prepare.join()
    wandb_run.finish()
    print(json.dumps({"calls": calls, "unguarded": unguarded, "overlapping": overlapping}))


if __name__ == "__main__":
    main(sys.argv[1])
