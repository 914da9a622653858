"""MuJoCo Playground's DeepMind Control Suite tasks as our environments, by name.

    env = envs.make("playground/CartpoleBalance")        # pip install -e ".[playground]"

Playground (``playground==0.2.0``, imported as ``mujoco_playground``) is optional and imported
on the first ``make`` of such a name only. Each task is loaded raw, with no Brax wrapper:
``registry.load(task, config_overrides={"impl": impl})``, MJX (``impl="jax"``) by default,
which steps these tasks 30-50x faster than its MuJoCo Warp default on a CPU and 1.5-2.0x
faster on an H100 (4,096 environments; BENCHMARKS.md). The adapter
(`envs.task_adapter.TaskAdapter`) makes the task's 1000-step limit a truncation with the true
final observation, its ``done`` a termination (Playground sets it on a non-finite state only),
takes actions in the actuators' ``ctrlrange`` ([-1, 1] throughout the suite) and observations
as the task's array.
"""

from __future__ import annotations

import contextlib
import functools
import warnings

from envs import _lean_import, task_adapter
from envs.task_adapter import TaskAdapter

PREFIX = "playground/"
INSTALL = 'pip install -e ".[playground]"'

TASKS = ("AcrobotSwingup", "AcrobotSwingupSparse", "BallInCup", "CartpoleBalance",
         "CartpoleBalanceSparse", "CartpoleSwingup", "CartpoleSwingupSparse", "CheetahRun",
         "FingerSpin", "FingerTurnEasy", "FingerTurnHard", "FishSwim", "HopperHop",
         "HopperStand", "HumanoidStand", "HumanoidWalk", "HumanoidRun", "PendulumSwingup",
         "PointMass", "ReacherEasy", "ReacherHard", "SwimmerSwimmer6", "WalkerRun",
         "WalkerStand", "WalkerWalk")
"""Playground 0.2.0's DeepMind Control Suite (`mujoco_playground.dm_control_suite.ALL_ENVS`,
checked by tests/test_playground.py), listed here so that naming them needs no import."""

SOLVED = {"CartpoleBalance": 900.0, "CartpoleSwingup": 800.0, "PendulumSwingup": 300.0}
"""Returns (of 1000) at which a task counts as solved: SAC's after 1M steps in TD-MPC2's
baselines (cartpole balance 998, swingup 839, pendulum swingup 354) rounded down to a hundred.
Other tasks have none set (AcrobotSwingup: no such figure at hand)."""


def task_name(name: str) -> str:
    """The Playground task of ``playground/<Task>``; ValueError naming close names if unknown."""
    return task_adapter.task_name(name, PREFIX, TASKS, "Playground task")


@functools.lru_cache(maxsize=None)
def _load(task: str, impl: str):
    if impl == "warp":  # imported before MJX, which then loads its Warp backend
        try:
            import warp
        except ImportError:
            raise ValueError(f"{PREFIX + task} with impl='warp' needs MuJoCo Warp: "
                             f"{INSTALL}") from None
        if _lean_import.mjx_loaded_without_warp():
            raise ValueError(f"{PREFIX + task} with impl='warp': this process has loaded MJX "
                             "without Warp (for an MJX task built before); build Warp tasks "
                             "in a process of their own")
        if warp.config.log_level == warp.LOG_INFO:  # its default: a line per kernel module loaded
            warp.config.log_level = warp.LOG_WARNING
    try:
        # without PyTorch (for its RSL-RL wrapper) and, for an MJX task, without Warp
        with _lean_import.mjx_import("torch"):  # Warp stays if imported above
            from mujoco_playground import registry
    except ImportError:
        raise ValueError(f"environment {PREFIX + task!r} needs MuJoCo Playground: "
                         f"{INSTALL}") from None
    with _mujoco_warnings_as_python():
        return registry.load(task, config_overrides={"impl": impl})


@contextlib.contextmanager
def _mujoco_warnings_as_python():
    """MuJoCo's warnings (e.g. CheetahRun's model uses the deprecated `settotalmass`) as Python
    warnings, which a user can filter: MuJoCo's own handler prints them to stdout and appends
    them to MUJOCO_LOG.TXT in the working directory."""
    import mujoco

    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda message: warnings.warn(f"MuJoCo: {message}",
                                                              stacklevel=2))
    try:
        yield
    finally:
        mujoco.set_mju_user_warning(previous)


class PlaygroundTask(TaskAdapter):
    """One Playground task behind our `Env` interface (see the module docstring).

    impl: "jax" (MJX, the default) or "warp" (MuJoCo Warp).
    """

    def __init__(self, name: str, *, impl: str = "jax"):
        if impl not in ("jax", "warp"):
            raise ValueError(f"{name}: impl={impl!r}; expected 'jax' (MJX) or 'warp'")
        task = _load(task_name(name), impl)
        # its episode_length: a limit Playground leaves to wrappers
        super().__init__(name, task, task.mj_model, task._config.episode_length, task.dt)

    @staticmethod
    def physics(data):
        return data.data
