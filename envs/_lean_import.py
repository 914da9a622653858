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

And two modules imported later, when first used: trimesh (which imports networkx and
scipy.ndimage) and scipy.spatial, which MJX's `mujoco.mjx._src.mesh` imports for the convex
hulls of colliding mesh geoms, computed when a model with them is put on the device. Deferring
trimesh (0.5 s, `python -X importtime`), building `InvertedPendulum-v5` in a new process took
1.67-2.32 s (median 1.86 s) instead of 2.13-2.74 s (median 2.57 s); deferring scipy.spatial as
well, 1.49-1.80 s (median 1.65 s) instead of 1.83-2.44 s (median 2.09 s) with trimesh alone (5
and 6 runs each, alternated, 2 CPU cores, AMD EPYC).
"""

from __future__ import annotations

import contextlib
import importlib
import io
import sys
import types


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


class _Deferred(types.ModuleType):
    """Stands in for the module `name` in the modules imported while `deferred` is open: its
    attributes are the real module's, imported at the first lookup, except the names given as
    placeholders, which stay placeholders while `deferred` is open (for annotations evaluated at
    import, such as ``tm: trimesh.Trimesh``) and are the real ones afterwards."""

    def __init__(self, name: str, placeholders):
        super().__init__(name, f"{name}, imported when first used (envs._lean_import)")
        self._placeholders = {p: type(p, (), {"__module__": name}) for p in placeholders}

    def __getattr__(self, attribute: str):
        if attribute.startswith("__") or attribute == "_placeholders":
            raise AttributeError(attribute)
        if sys.modules.get(self.__name__) is self:  # still deferred
            if attribute in self._placeholders:
                return self._placeholders[attribute]
            del sys.modules[self.__name__]
        real = importlib.import_module(self.__name__)
        return getattr(real, attribute)


@contextlib.contextmanager
def deferred(name: str, *placeholders: str):
    """Inside, importing the module `name` gives a `_Deferred` stand-in that imports the
    module when one of its attributes is first looked up (unless it is imported already);
    `placeholders` are attribute names the stand-in answers without importing it while open.
    Afterwards `import name` imports the module itself."""
    if name in sys.modules:
        yield
        return
    stand_in = sys.modules[name] = _Deferred(name, placeholders)
    try:
        yield
    finally:
        if sys.modules.get(name) is stand_in:
            del sys.modules[name]


@contextlib.contextmanager
def mjx_import(*hidden: str):
    """For importing MJX (or a package that imports it): Warp and the packages `hidden`
    hidden (`without`), trimesh and scipy.spatial deferred (`deferred`; the name MJX's
    annotations read, ``Trimesh``, is a placeholder meanwhile)."""
    with without("warp", *hidden), deferred("trimesh", "Trimesh"), deferred("scipy.spatial"):
        yield
