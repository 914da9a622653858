"""Quiet, light import of MuJoCo XLA (MJX).

``from mujoco import mjx`` prints "Failed to import warp..." on stdout when the optional
Warp backend is missing, and imports Warp (seconds) where it is installed. Every module of
:mod:`envs` imports ``mjx`` from here, with Warp hidden (`envs._lean_import`), so that
importing an MJX environment prints nothing and loads no Warp.
"""

import importlib.metadata

from envs import _lean_import

WRITTEN_FOR = {"mujoco": "4.0.0", "mujoco-mjx": "3.17.0"}
"""The versions whose private MJX modules (``mujoco.mjx._src``) envs/ was written and tested
against; the project pins them. Another version may rename or change what is used here."""


def check_versions(installed=None) -> None:
    """Raises ImportError (one line) unless the installed mujoco and mujoco-mjx are those of
    `WRITTEN_FOR`. `installed`: name -> version, by default read from the installed packages."""
    for name, wanted in WRITTEN_FOR.items():
        found = (installed or {}).get(name) or importlib.metadata.version(name)
        if found != wanted:
            raise ImportError(
                f"envs needs {name}=={wanted} (it uses MJX's private modules of that version), "
                f"found {found}: pip install {name}=={wanted}")


check_versions()

with _lean_import.mjx_import():
    from mujoco import mjx
    # MJX internals used by the single-forward RK4 step (envs.mjx_env.MjxEnv._rk4); the
    # project pins mujoco-mjx, so these private names are stable for it.
    from mujoco.mjx._src import forward as mjx_forward
    from mujoco.mjx._src import scan as mjx_scan
    # and by the forward dynamics with the active-set constraint solver (envs.active_set_solver)
    from mujoco.mjx._src import sensor as mjx_sensor
    from mujoco.mjx._src import solver as mjx_solver
    from mujoco.mjx._src import support as mjx_support

__all__ = ["mjx", "mjx_forward", "mjx_scan", "mjx_sensor", "mjx_solver", "mjx_support"]
