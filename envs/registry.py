"""Environment names and ``make``."""

from __future__ import annotations

import functools
import inspect

from envs import cartpole
from envs.double_pendulum import InvertedDoublePendulum
from envs.pendulum import Pendulum
from envs.types import Env

DEFAULT_ENV = "InvertedPendulum-v5"

_FACTORIES = {
    "InvertedPendulum-v5": functools.partial(cartpole.CartPole, variant=cartpole.V5),
    "InvertedPendulum-v4": functools.partial(cartpole.CartPole, variant=cartpole.V4),
    "InvertedPendulumBullet-v0": functools.partial(cartpole.CartPole, variant=cartpole.BULLET),
    "InvertedDoublePendulum-v5": InvertedDoublePendulum,
    "Pendulum-v1": Pendulum,
}

SOLVED_RETURN = {
    "InvertedPendulum-v5": 950.0,
    "InvertedPendulum-v4": 950.0,
    "InvertedPendulumBullet-v0": 950.0,
    "InvertedDoublePendulum-v5": 9000.0,
    "Pendulum-v1": -250.0,
}
"""Mean deterministic evaluation return at which each task counts as solved."""


def registered() -> tuple[str, ...]:
    """Names accepted by :func:`make`."""
    return tuple(_FACTORIES)


def options(name: str) -> dict[str, object]:
    """Options of environment ``name`` and their defaults."""
    factory = _factory(name)
    signature = inspect.signature(factory)
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
    return _factory(name)(name, **kwargs)


def _factory(name: str):
    if name not in _FACTORIES:
        raise ValueError(f"unknown environment {name!r}; registered: {', '.join(_FACTORIES)}")
    return _FACTORIES[name]
