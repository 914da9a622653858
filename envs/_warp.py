"""MJX without MuJoCo Warp: importing MJX where Warp is installed (the `playground` and test
extras pull warp-lang) also imports Warp and MJX's Warp backend, for a backend that no task
here steps unless asked (`impl="warp"` of a Playground task). `hidden` keeps them out: a warm
`python scripts/train.py` with warp-lang installed reached its solved policy 5.5-5.8 s from
process start instead of 7.2-7.7 s (2 CPU cores, AMD EPYC, 4 runs each, alternated)."""

from __future__ import annotations

import contextlib
import io
import sys


@contextlib.contextmanager
def hidden():
    """Inside, ``import warp`` fails as if Warp were not installed, unless Warp is imported
    already; MJX's line saying so ("Failed to import warp") is kept off stdout."""
    hide = "warp" not in sys.modules
    if hide:
        sys.modules["warp"] = None  # an import of a module set to None raises ImportError
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            yield
    finally:
        if hide and "warp" in sys.modules and sys.modules["warp"] is None:
            del sys.modules["warp"]


def mjx_loaded_without_warp() -> bool:
    """Whether this process has imported MJX without its Warp backend."""
    backend = sys.modules.get("mujoco.mjx.warp")
    return backend is not None and not backend.WARP_INSTALLED
