"""Brax's environments as ours, by name: ``envs.make("brax/ant")``.

Brax (a dependency of sac-jax) is imported on the first ``make`` of such a name only. Each task
is Brax's environment on its MJX pipeline (``brax.envs.get_environment(task, backend="mjx")``)
with none of Brax's training wrappers; the adapter (`envs.task_adapter.TaskAdapter`) makes the
1000-step limit of Brax's ``EpisodeWrapper`` (``brax.envs.create``'s default) a truncation with
the true final observation, and Brax's ``done`` (an unhealthy body, where the task has that
rule) a termination. Actions are in the actuators' ``ctrlrange``, except for the tasks of
`UNIT_ACTIONS`, whose step takes actions in [-1, 1] and maps them onto that range itself.

Brax no longer maintains its environments (a notice it prints on loading one, silenced here);
MuJoCo Playground (``playground/<Task>``, envs/playground.py) holds the maintained MJX tasks.
"""

from __future__ import annotations

import functools
import warnings

from envs import _lean_import, task_adapter
from envs.task_adapter import TaskAdapter

PREFIX = "brax/"

TASKS = ("ant", "halfcheetah", "hopper", "humanoid", "humanoidstandup",
         "inverted_double_pendulum", "inverted_pendulum", "pusher", "reacher", "swimmer",
         "walker2d")
"""Brax 0.14.2's MuJoCo environments (`brax.envs._envs` without its test task "fast", checked
by tests/test_brax_tasks.py), listed here so that naming them needs no import."""

UNIT_ACTIONS = ("humanoid", "humanoidstandup", "inverted_pendulum", "pusher")
"""The tasks whose ``step`` maps an action in [-1, 1] affinely onto the actuators'
``ctrlrange`` before the physics (checked by tests/test_brax_tasks.py). Offered that range
instead, inverted_pendulum's [-3, 3] became controls of 3a, clamped: only a third of it moved
the cart, and humanoid's [-0.4, 0.4] became 0.4a, 40 % of its actuators' range."""
EPISODE_LENGTH = 1000
"""Steps before a truncation: `brax.envs.create`'s default `episode_length`."""


def task_name(name: str) -> str:
    """The Brax environment of ``brax/<task>``; ValueError naming close names if unknown."""
    return task_adapter.task_name(name, PREFIX, TASKS, "Brax environment")


@functools.lru_cache(maxsize=None)
def _load(task: str):
    with _lean_import.mjx_import():  # Brax's MJX pipeline steps without Warp
        from brax import envs as brax_envs
    with warnings.catch_warnings():  # Brax's notice that its environments are unmaintained
        warnings.filterwarnings("ignore", "Brax System, piplines and environments")
        return brax_envs.get_environment(task, backend="mjx")


class BraxTask(TaskAdapter):
    """One Brax environment behind our `Env` interface (see the module docstring)."""

    def __init__(self, name: str):
        brax_name = task_name(name)
        task = _load(brax_name)
        super().__init__(name, task, task.sys.mj_model, EPISODE_LENGTH, task.dt,
                         unit_actions=brax_name in UNIT_ACTIONS)

    @staticmethod
    def physics(data):
        return data.pipeline_state
