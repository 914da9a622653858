"""MuJoCo Playground's DeepMind Control Suite tasks as our environments, by name.

    env = envs.make("playground/CartpoleBalance")        # pip install -e ".[playground]"

Playground (``playground==0.2.0``, imported as ``mujoco_playground``) is optional and imported
on the first ``make`` of such a name only. Each task is loaded raw, with no Brax wrapper:
``registry.load(task, config_overrides={"impl": impl})``, MJX (``impl="jax"``) by default,
which steps 30-50x faster than its MuJoCo Warp default on a CPU. What the adapter does:

* **Time limit = truncation.** Playground's tasks end only on a non-finite state (``done``);
  their limit of ``episode_length`` control steps (1000) is left to Brax's ``EpisodeWrapper``,
  whose ``BraxAutoResetWrapper`` also overwrites the final observation. Here ``truncated`` is
  ``step_count >= episode_length`` (our rule for every environment) and the step returns the
  true final observation, which a truncated transition bootstraps from.
* **``done`` = termination**: ``terminated = done > 0``, or a non-finite action (our rule: the
  non-finite components become 0 and the step terminates).
* **Actions** in the task's own units: ``action_low``/``action_high`` are the actuators'
  ``ctrlrange`` ([-1, 1] throughout the suite), and the action, clipped there, is the task's.
* **Observations**: the task's array (a dict observation's ``"state"`` entry).
* The whole Playground ``State`` (MJX data, info with its key, metrics) is our ``data``, so
  ``reset(key)`` draws a fresh random start per key, as the task does.
"""

from __future__ import annotations

import difflib
import functools

import jax
import jax.numpy as jnp
import numpy as np

from envs.types import Env, EnvState

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

SOLVED = {"CartpoleBalance": 900.0, "CartpoleSwingup": 800.0}
"""Returns (of 1000) at which a task counts as solved, where one is set."""


def task_name(name: str) -> str:
    """The Playground task of ``playground/<Task>``; ValueError naming close names if unknown."""
    task = name[len(PREFIX):]
    if task not in TASKS:
        close = difflib.get_close_matches(task, TASKS, n=3, cutoff=0.5)
        hint = (f"did you mean {', '.join(PREFIX + c for c in close)}?" if close
                else f"known: {', '.join(PREFIX + t for t in TASKS)}")
        raise ValueError(f"unknown Playground task {name!r}; {hint}")
    return task


@functools.lru_cache(maxsize=None)
def _load(task: str, impl: str):
    try:
        from mujoco_playground import registry
    except ImportError:
        raise ValueError(f"environment {PREFIX + task!r} needs MuJoCo Playground: "
                         f"{INSTALL}") from None
    return registry.load(task, config_overrides={"impl": impl})


class PlaygroundTask(Env):
    """One Playground task behind our `Env` interface (see the module docstring).

    impl: "jax" (MJX, the default) or "warp" (MuJoCo Warp).
    """

    simulates_mujoco = True

    def __init__(self, name: str, *, impl: str = "jax"):
        if impl not in ("jax", "warp"):
            raise ValueError(f"{name}: impl={impl!r}; expected 'jax' (MJX) or 'warp'")
        self._task = _load(task_name(name), impl)
        model = self._task.mj_model
        limited = np.asarray(model.actuator_ctrllimited, bool)
        ranges = np.asarray(model.actuator_ctrlrange, np.float32)
        low = np.where(limited, ranges[:, 0], -1.0)
        high = np.where(limited, ranges[:, 1], 1.0)
        size = self._task.observation_size
        size = size["state"] if isinstance(size, dict) else size
        config = self._task._config  # its episode_length: a limit Playground leaves to wrappers
        super().__init__(name, int(np.prod(size)), low, high, config.episode_length,
                         self._task.dt)

    @property
    def task(self):
        """The Playground `MjxEnv` stepped."""
        return self._task

    @property
    def mj_model(self):
        """The task's MuJoCo model (scripts/render.py poses it)."""
        return self._task.mj_model

    @staticmethod
    def _obs(state) -> jax.Array:
        obs = state.obs["state"] if isinstance(state.obs, dict) else state.obs
        return jnp.ravel(obs)

    def reset(self, key: jax.Array) -> EnvState:
        state = self._task.reset(key)
        return self._initial_state(self._obs(state), state)

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        action, finite = self._sanitize_action(action)
        after = self._task.step(state.data, action)
        return self._next_state(state, self._obs(after), after.reward,
                                (after.done > 0) | ~finite, after)
