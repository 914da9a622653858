"""The environment registry: one `EnvSpec` per environment, and ``make``.

Adding an environment is one module (its `Env` subclass) and one `EnvSpec` line in `SPECS`.
Presets, scripts (evaluation against Gymnasium, rendering), `sac_jax.run`'s solved counts and
the learning tests read an environment's facts from its spec.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import inspect
from typing import Callable, Literal, Optional

from envs import brax_tasks, playground
from envs.pendulum import Pendulum
from envs._validate import unknown_name
from envs.types import Env

DEFAULT_ENV = "InvertedPendulum-v5"


@dataclasses.dataclass(frozen=True)
class EnvSpec:
    """What sac-jax knows of one environment.

    name            the registered name (`make(name)`)
    factory         `factory(name, **options) -> Env`; its keyword-only parameters are the
                    environment's options (`options(name)`)
    solved_return   mean deterministic evaluation return at which the task counts as solved
    gymnasium_id    Gymnasium's id of the same task, stepped as ours is (tests/test_envs.py),
                    or None where Gymnasium has no twin
    renderer        how scripts/render.py draws it: "mujoco" (MuJoCo's renderer on the MJCF
                    model, posed from qpos) or "pendulum" (matplotlib)
    The observation and action spaces are the built environment's (`observation_size`,
    `action_size`, `action_low`, `action_high`).
    """

    name: str
    factory: Callable[..., Env]
    solved_return: Optional[float]
    gymnasium_id: Optional[str]
    renderer: Literal["mujoco", "pendulum"]


class _Deferred:
    """The factory `module.attribute` (`variant`: the name of one of the module's cart-pole
    variants, passed as `variant=`), imported when first called or inspected: the MJX
    environments' modules import MuJoCo XLA, which costs a process about 1 s at start and 0.25 s
    at exit (2 s and 0.9 s where Warp is installed), and a Pendulum-v1 run needs none of it."""

    def __init__(self, module: str, attribute: str, variant: Optional[str] = None):
        self._where = (module, attribute, variant)

    def _factory(self) -> Callable[..., Env]:
        module, attribute, variant = self._where
        module = importlib.import_module(module)
        factory = getattr(module, attribute)
        return factory if variant is None else functools.partial(
            factory, variant=getattr(module, variant))

    def __call__(self, *args, **kwargs) -> Env:
        return self._factory()(*args, **kwargs)

    @property
    def __signature__(self) -> inspect.Signature:
        return inspect.signature(self._factory())


SPECS = {spec.name: spec for spec in (
    EnvSpec("InvertedPendulum-v5", _Deferred("envs.cartpole", "CartPole", "V5"),
            950.0, "InvertedPendulum-v5", "mujoco"),
    EnvSpec("InvertedPendulum-v4", _Deferred("envs.cartpole", "CartPole", "V4"),
            950.0, "InvertedPendulum-v4", "mujoco"),
    EnvSpec("InvertedPendulumBullet-v0", _Deferred("envs.cartpole", "CartPole", "BULLET"),
            950.0, None, "mujoco"),
    EnvSpec("InvertedDoublePendulum-v5",
            _Deferred("envs.double_pendulum", "InvertedDoublePendulum"), 9000.0,
            "InvertedDoublePendulum-v5", "mujoco"),
    EnvSpec("Pendulum-v1", Pendulum, -250.0, "Pendulum-v1", "pendulum"),
)}


def registered() -> tuple[str, ...]:
    """Names accepted by :func:`make`: ours, then MuJoCo Playground's DeepMind Control Suite
    tasks as ``playground/<Task>`` (envs/playground.py; they need the ``playground`` extra),
    then Brax's environments as ``brax/<task>`` (envs/brax_tasks.py)."""
    return (tuple(SPECS) + tuple(playground.PREFIX + task for task in playground.TASKS)
            + tuple(brax_tasks.PREFIX + task for task in brax_tasks.TASKS))


def spec(name: str) -> EnvSpec:
    """The `EnvSpec` of environment ``name``; ValueError naming close registered names."""
    if name.startswith(playground.PREFIX):
        task = playground.task_name(name)
        return EnvSpec(name, playground.PlaygroundTask, playground.SOLVED.get(task), None,
                       "mujoco")
    if name.startswith(brax_tasks.PREFIX):
        brax_tasks.task_name(name)
        return EnvSpec(name, brax_tasks.BraxTask, None, None, "mujoco")
    if name not in SPECS:
        raise unknown_name("environment", name, registered(),
                           f"registered: {', '.join(SPECS)}, playground/<Task> and brax/<task>")
    return SPECS[name]


def options(name: str) -> dict[str, object]:
    """Options of environment ``name`` and their defaults."""
    signature = inspect.signature(spec(name).factory)
    return {
        p.name: p.default
        for p in signature.parameters.values()
        if p.kind is inspect.Parameter.KEYWORD_ONLY and p.name != "variant"
    }


def make(name: str = DEFAULT_ENV, **kwargs) -> Env:
    """Build environment ``name`` with keyword options (see :func:`options`).

    Raises:
        ValueError: unknown name, or an option value out of its range.
        TypeError: unknown option name, or an option of the wrong type.
    """
    accepted = options(name)
    unknown = sorted(set(kwargs) - set(accepted))
    if unknown:
        raise TypeError(
            f"unknown option(s) {unknown} for {name}; accepted options: {sorted(accepted)}"
        )
    return spec(name).factory(name, **kwargs)
