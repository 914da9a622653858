"""The part shared by the adapters of other libraries' MJX tasks (MuJoCo Playground's in
envs/playground.py, Brax's in envs/brax_tasks.py): a task whose ``reset(key)`` and
``step(state, action)`` return a state with ``obs``, ``reward`` and ``done``, behind our `Env`.

* **Time limit = truncation.** Neither library's task counts its steps: the limit of
  ``episode_length`` steps is left to wrappers (Brax's ``EpisodeWrapper``; its
  ``AutoResetWrapper`` also overwrites the final observation). Here ``truncated`` is ``step_count >=
  episode_length`` (our rule for every environment), and the step returns the true final
  observation, which a truncated transition bootstraps from.
* **``done`` = termination**: ``terminated = done > 0``, or a non-finite action (our rule: the
  non-finite components become 0 and the step terminates).
* **Actions** in the task's own units: ``action_low``/``action_high`` are the actuators'
  ``ctrlrange`` (-1, 1 where an actuator is not limited), and the clipped action is the task's.
* **Observations**: the task's array, flattened (a dict observation's ``"state"`` entry).
* The task's whole state is our ``data``, so ``reset(key)`` draws a fresh random start per
  key, as the task does.
"""

from __future__ import annotations

import functools
from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from envs._validate import unknown_name
from envs.types import Env, EnvState


def task_name(name: str, prefix: str, tasks: Sequence[str], library: str) -> str:
    """The task of ``<prefix><task>`` among `tasks`; ValueError ("unknown <library> task",
    naming close names) if it is not one."""
    task = name[len(prefix):]
    if task not in tasks:
        raise unknown_name(library, name, tasks, f"known: {', '.join(prefix + t for t in tasks)}",
                           prefix)
    return task


@functools.lru_cache(maxsize=None)
def observation_size(task) -> int:
    """The length of `task`'s flattened observation (its dict's "state" entry). Kept per task
    object (each adapter loads a task once per process): both libraries' `observation_size`
    traces the task's reset, 0.3-1.1 s for a Playground task, and a run builds its
    environment several times."""
    size = task.observation_size
    return int(np.prod(size["state"] if isinstance(size, dict) else size))


class TaskAdapter(Env):
    """`task` (reset/step as above; `observation_size` an int, a shape, or a dict of them with
    a "state" entry) behind our `Env` interface, its actuators read from the MuJoCo model
    `mj_model`: actions in their `ctrlrange` (in [-1, 1] where unlimited), or in [-1, 1] with
    `unit_actions`, for a task whose step maps [-1, 1] onto the `ctrlrange` itself."""

    simulates_mujoco = True

    def __init__(self, name: str, task, mj_model, episode_length: int, dt: float,
                 unit_actions: bool = False):
        self._task, self._mj_model = task, mj_model
        limited = np.asarray(mj_model.actuator_ctrllimited, bool)
        ranges = np.asarray(mj_model.actuator_ctrlrange, np.float32)
        low = np.where(limited & ~unit_actions, ranges[:, 0], -1.0)
        high = np.where(limited & ~unit_actions, ranges[:, 1], 1.0)
        super().__init__(name, observation_size(task), low, high, int(episode_length),
                         float(dt))

    @property
    def task(self):
        """The task stepped."""
        return self._task

    @property
    def mj_model(self):
        """The task's MuJoCo model (scripts/render.py poses it)."""
        return self._mj_model

    @staticmethod
    def physics(data):
        """The MJX data (`qpos`, `qvel`, ...) inside the task's state `data`."""
        raise NotImplementedError

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
