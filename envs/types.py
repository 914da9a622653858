"""Environment state and the interface shared by every environment.

An environment is an immutable Python object holding constants (model, bounds, options);
all changing quantities live in an :class:`EnvState` pytree::

    state = env.reset(key)            # key: jax PRNG key
    state = env.step(state, action)   # action: (action_size,)

Both functions are pure, jit-able and vmappable.  Environment objects are hashable by
identity and are meant to be closed over (or passed as static arguments), not traced.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct


class EnvState(struct.PyTreeNode):
    """State of one environment after ``reset`` or ``step``.

    Attributes:
        obs: (observation_size,) float32, observation of the current state.
        reward: () float32, reward of the transition that produced this state (0 after reset).
        terminated: () bool, the MDP reached a terminal state (or the action was non-finite).
        truncated: () bool, ``step_count >= max_episode_steps`` (Gymnasium's TimeLimit rule).
        step_count: () int32, number of steps since the last reset.
        data: physics state: ``mjx.Data`` for MJX environments, a small pytree otherwise.
    """

    obs: jax.Array
    reward: jax.Array
    terminated: jax.Array
    truncated: jax.Array
    step_count: jax.Array
    data: Any


class Env:
    """Interface and shared bookkeeping of all environments.

    Subclasses implement ``reset(key) -> EnvState`` and ``step(state, action) -> EnvState``.

    Non-finite action rule (all environments): each non-finite action component is replaced
    by 0 before it reaches the physics, the remaining components are clipped to
    ``[action_low, action_high]`` (as MuJoCo clamps ``ctrl`` to ``ctrlrange``), and the step
    reports ``terminated=True``.  The state therefore stays finite.

    ``reset`` and ``step`` of every instance are ``jax.jit``-wrapped once at construction: a
    training program calls them from several places (vectorised stepping, auto-reset,
    evaluation), and a jitted function is traced once per input shape and reused at each call
    site, which cuts the Python tracing time of an MJX training program.

    ``simulates_mujoco``: whether the step runs MuJoCo physics (MJX or MuJoCo Warp), whose
    traced step makes most of a training program (`sac_jax.compilation_cache` compiles such
    programs differently on a CPU).
    """

    simulates_mujoco = False

    def __init__(
        self,
        name: str,
        observation_size: int,
        action_low: np.ndarray,
        action_high: np.ndarray,
        max_episode_steps: int,
        dt: float,
    ):
        self._name = name
        self._observation_size = int(observation_size)
        self._action_low = np.asarray(action_low, dtype=np.float32).reshape(-1)
        self._action_high = np.asarray(action_high, dtype=np.float32).reshape(-1)
        self._max_episode_steps = int(max_episode_steps)
        self._dt = float(dt)
        self.reset = jax.jit(self.reset)
        self.step = jax.jit(self.step)

    @property
    def name(self) -> str:
        return self._name

    @property
    def observation_size(self) -> int:
        return self._observation_size

    @property
    def action_size(self) -> int:
        return self._action_low.shape[0]

    @property
    def action_low(self) -> np.ndarray:
        """(action_size,) float32 lower action bound (a copy)."""
        return self._action_low.copy()

    @property
    def action_high(self) -> np.ndarray:
        """(action_size,) float32 upper action bound (a copy)."""
        return self._action_high.copy()

    @property
    def max_episode_steps(self) -> int:
        return self._max_episode_steps

    @property
    def dt(self) -> float:
        """Simulated seconds per ``step``."""
        return self._dt

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self._name}>"

    def reset(self, key: jax.Array) -> EnvState:
        raise NotImplementedError

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        raise NotImplementedError

    def _sanitize_action(self, action: jax.Array) -> tuple[jax.Array, jax.Array]:
        """Apply the non-finite action rule.

        Returns ``(a, finite)`` with ``a = clip(where(isfinite(action), action, 0), low, high)``
        of shape (action_size,) and ``finite = all(isfinite(action))`` of shape ().
        """
        action = jnp.asarray(action)
        if action.shape != (self.action_size,):
            raise ValueError(
                f"{self._name}: action shape {action.shape} != ({self.action_size},)"
            )
        finite = jnp.isfinite(action)
        clean = jnp.clip(jnp.where(finite, action, 0), self._action_low, self._action_high)
        return clean, jnp.all(finite)

    def _initial_state(self, obs: jax.Array, data: Any) -> EnvState:
        """EnvState right after a reset: reward 0, flags False, step_count 0."""
        return EnvState(
            obs=obs.astype(jnp.float32),
            reward=jnp.zeros((), jnp.float32),
            terminated=jnp.zeros((), bool),
            truncated=jnp.zeros((), bool),
            step_count=jnp.zeros((), jnp.int32),
            data=data,
        )

    def _next_state(
        self, state: EnvState, obs: jax.Array, reward: jax.Array, terminated: jax.Array, data: Any
    ) -> EnvState:
        """EnvState after one step; ``truncated = step_count + 1 >= max_episode_steps``."""
        step_count = state.step_count + 1
        return EnvState(
            obs=obs.astype(jnp.float32),
            reward=jnp.asarray(reward, jnp.float32),
            terminated=jnp.asarray(terminated, bool),
            truncated=step_count >= self._max_episode_steps,
            step_count=step_count,
            data=data,
        )
