"""Imports of MJX, Playground and Brax without the optional packages they pull in for work no
task here does:

* MuJoCo Warp: MJX imports it, and its Warp backend, wherever warp-lang is installed (the
  `playground` and `test` extras pull it), for a backend no task steps unless asked
  (`impl="warp"` of a Playground task). Without it a warm `python scripts/train.py` reached its
  solved policy 5.5-5.8 s from process start instead of 7.2-7.7 s (2 CPU cores, AMD EPYC, 4
  runs each, alternated).
* PyTorch: Playground imports it, where installed (the `test` extra), for its RSL-RL wrapper
  (which then stays unusable in that process): `from mujoco_playground import registry` took
  0.72-0.77 s instead of 1.88-1.89 s (2 runs each, Warp hidden in both).

With both hidden, `python scripts/train.py --preset CartpoleBalance` (warm cache) started its
run 3.7-3.9 s after process start instead of 6.3-6.5 s (2 warm runs each, alternated).
"""

from __future__ import annotations

import contextlib
import io
import sys


@contextlib.contextmanager
def without(*names: str):
    """Inside, importing any of the top-level packages `names` fails as if it were not
    installed, unless it is imported already; the lines MJX and Playground print when one is
    missing ("Failed to import warp") are kept off stdout. Afterwards they import as usual."""
    hidden = [name for name in names if name not in sys.modules]
    for name in hidden:
        sys.modules[name] = None  # an import of a module set to None raises ImportError
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            yield
    finally:
        for name in hidden:
            if name in sys.modules and sys.modules[name] is None:
                del sys.modules[name]


def mjx_loaded_without_warp() -> bool:
    """Whether this process has imported MJX without its Warp backend."""
    backend = sys.modules.get("mujoco.mjx.warp")
    return backend is not None and not backend.WARP_INSTALLED
