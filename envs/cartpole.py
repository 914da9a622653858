"""MJX cart-pole family: InvertedPendulum-v5, InvertedPendulum-v4, InvertedPendulumBullet-v0.

All three share Gymnasium's inverted-pendulum model (below, written from its parameters):
a cart on a slider (range ±1 m, damping 1) carrying a pole on a hinge (range ±90°,
damping 1); a motor on the slider with gear 100 and ctrlrange ±3; RK4 with timestep 0.02 s
and frame_skip 2 (dt = 0.04 s); gravity -9.81; no contacts.

State q = (x, θ), q̇ = (ẋ, θ̇).  Per step, with the non-finite action rule of
:class:`envs.types.Env` giving a clipped action a and the flag ``finite``:

    ctrl        = action_scale · a                         (1 for v4/v5, 3 for Bullet)
    terminated  = |θ'| > 0.2  ∨  obs' not finite  ∨  ¬finite
    reward      = 1 − [terminated]    (v5, Bullet)      reward = 1    (v4)
    obs         = (x, θ, ẋ, θ̇) ∈ R⁴                (v4, v5)
    obs         = (x, ẋ, cos θ, sin θ, θ̇) ∈ R⁵     (Bullet)

Reset: q, q̇ ~ U(−s, s) each (s = ``reset_noise_scale``, default 0.01).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from envs import _validate
from envs.mjx_env import MjxEnv
from envs.types import EnvState

CARTPOLE_XML = """
<mujoco model="inverted_pendulum">
  <compiler inertiafromgeom="true"/>
  <default>
    <joint armature="0" damping="1" limited="true"/>
    <geom contype="0" friction="1 0.1 0.1"/>
    <motor ctrlrange="-3 3"/>
  </default>
  <option gravity="0 0 -9.81" integrator="RK4" timestep="0.02"/>
  <worldbody>
    <geom name="rail" type="capsule" pos="0 0 0" quat="0.707 0 0.707 0" size="0.02 1"/>
    <body name="cart" pos="0 0 0">
      <joint name="slider" type="slide" axis="1 0 0" pos="0 0 0" range="-1 1"/>
      <geom name="cart" type="capsule" pos="0 0 0" quat="0.707 0 0.707 0" size="0.1 0.1"/>
      <body name="pole" pos="0 0 0">
        <joint name="hinge" type="hinge" axis="0 1 0" pos="0 0 0" range="-90 90"/>
        <geom name="cpole" type="capsule" fromto="0 0 0 0.001 0 0.6" size="0.049 0.3"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="slide" joint="slider" gear="100" ctrllimited="true" ctrlrange="-3 3"/>
  </actuator>
</mujoco>
"""

MOTOR_LIMIT = 3.0  # ctrlrange of the slider motor


@dataclasses.dataclass(frozen=True)
class CartPoleVariant:
    """What distinguishes the members of the family.

    Attributes:
        bullet_obs: observe (x, ẋ, cos θ, sin θ, θ̇) instead of (x, θ, ẋ, θ̇).
        action_scale: ctrl = action_scale · action; the action bound is MOTOR_LIMIT / scale.
        reward_when_terminated: reward on the terminating step (1 for v4, 0 otherwise).
    """

    bullet_obs: bool
    action_scale: float
    reward_when_terminated: float


V5 = CartPoleVariant(bullet_obs=False, action_scale=1.0, reward_when_terminated=0.0)
V4 = CartPoleVariant(bullet_obs=False, action_scale=1.0, reward_when_terminated=1.0)
BULLET = CartPoleVariant(bullet_obs=True, action_scale=MOTOR_LIMIT, reward_when_terminated=0.0)


class CartPole(MjxEnv):
    """One member of the MJX cart-pole family (see the module docstring)."""

    def __init__(
        self,
        name: str,
        variant: CartPoleVariant,
        *,
        reset_noise_scale: float = 0.01,
        max_episode_steps: int = 1000,
    ):
        self._variant = variant
        self._reset_noise_scale = _validate.finite_float(
            "reset_noise_scale", reset_noise_scale, 0.0
        )
        bound = np.full((1,), MOTOR_LIMIT / variant.action_scale, np.float32)
        super().__init__(
            name,
            CARTPOLE_XML,
            frame_skip=2,
            observation_size=5 if variant.bullet_obs else 4,
            action_low=-bound,
            action_high=bound,
            max_episode_steps=_validate.positive_int("max_episode_steps", max_episode_steps),
        )

    def _observe(self, data) -> jax.Array:
        """(observation_size,) observation of ``data`` (before the float32 cast)."""
        (x, theta), (x_dot, theta_dot) = data.qpos, data.qvel
        if self._variant.bullet_obs:
            return jnp.stack([x, x_dot, jnp.cos(theta), jnp.sin(theta), theta_dot])
        return jnp.concatenate([data.qpos, data.qvel])

    def reset(self, key: jax.Array) -> EnvState:
        """q, q̇ ~ U(−s, s)² each; obs of that state; key: PRNG key."""
        key_q, key_v = jax.random.split(key)
        s = self._reset_noise_scale
        data = self._data_at(self._uniform_noise(key_q, 2, s), self._uniform_noise(key_v, 2, s),
                             forward=False)
        return self._initial_state(self._observe(data), data)

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        """One step of dt = 0.04 s; action (1,) (see the module docstring for the rules)."""
        action, finite = self._sanitize_action(action)
        data = self._simulate(state.data, self._variant.action_scale * action)
        obs = self._observe(data)
        terminated = (jnp.abs(data.qpos[1]) > 0.2) | ~jnp.all(jnp.isfinite(obs)) | ~finite
        reward = jnp.where(terminated, self._variant.reward_when_terminated, 1.0)
        return self._next_state(state, obs, reward, terminated, data)
