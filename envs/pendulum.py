"""Pure-JAX port of Gymnasium's classic-control Pendulum-v1.

State (θ, θ̇); g = 10 (option ``g``), m = 1, l = 1, dt = 0.05, |θ̇| ≤ 8, |u| ≤ 2.  One step,
with u the action after the non-finite rule of :class:`envs.types.Env` and clipping:

    reward = −(norm(θ)² + 0.1 θ̇² + 0.001 u²)     (pre-step state; norm(θ) = ((θ + π) mod 2π) − π)
    θ̇'     = clip(θ̇ + (3g/(2l) sin θ + 3/(m l²) u) dt, −8, 8)
    θ'     = θ + θ̇' dt
    obs    = (cos θ', sin θ', θ̇') ∈ R³

``terminated`` is True only on a non-finite action; truncation at 200 steps (option
``max_episode_steps``).  Reset: θ ~ U(−π, π), θ̇ ~ U(−1, 1).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from envs import _validate
from envs.types import Env, EnvState

MAX_SPEED = 8.0
MAX_TORQUE = 2.0
MASS = 1.0
LENGTH = 1.0
DT = 0.05


class PendulumData(struct.PyTreeNode):
    """Physics state of the pendulum: theta () angle (unnormalised), theta_dot () rad/s."""

    theta: jax.Array
    theta_dot: jax.Array


def _observe(data: PendulumData) -> jax.Array:
    """(3,) observation (cos θ, sin θ, θ̇)."""
    return jnp.stack([jnp.cos(data.theta), jnp.sin(data.theta), data.theta_dot])


class Pendulum(Env):
    """Pendulum-v1 swing-up (see the module docstring)."""

    def __init__(
        self, name: str = "Pendulum-v1", *, g: float = 10.0, max_episode_steps: int = 200
    ):
        self._g = _validate.finite_float("g", g)
        super().__init__(
            name,
            observation_size=3,
            action_low=np.full((1,), -MAX_TORQUE, np.float32),
            action_high=np.full((1,), MAX_TORQUE, np.float32),
            max_episode_steps=_validate.positive_int("max_episode_steps", max_episode_steps),
            dt=DT,
        )

    def reset(self, key: jax.Array) -> EnvState:
        """θ ~ U(−π, π), θ̇ ~ U(−1, 1); key: PRNG key."""
        high = jnp.array([jnp.pi, 1.0])
        theta, theta_dot = jax.random.uniform(key, (2,), high.dtype, minval=-high, maxval=high)
        data = PendulumData(theta=theta, theta_dot=theta_dot)
        return self._initial_state(_observe(data), data)

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        """One step of dt = 0.05 s; action (1,) torque."""
        action, finite = self._sanitize_action(action)
        u = action[0]
        theta, theta_dot = state.data.theta, state.data.theta_dot
        normalized = jnp.mod(theta + jnp.pi, 2 * jnp.pi) - jnp.pi
        cost = normalized**2 + 0.1 * theta_dot**2 + 0.001 * u**2
        acceleration = 3 * self._g / (2 * LENGTH) * jnp.sin(theta) + 3.0 / (MASS * LENGTH**2) * u
        new_theta_dot = jnp.clip(theta_dot + acceleration * DT, -MAX_SPEED, MAX_SPEED)
        data = PendulumData(theta=theta + new_theta_dot * DT, theta_dot=new_theta_dot)
        return self._next_state(state, _observe(data), -cost, ~finite, data)
