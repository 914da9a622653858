"""MJX InvertedDoublePendulum-v5 (Gymnasium's model and semantics).

Model (written from Gymnasium's parameters): a cart on a slider (range ±1 m with limit
margin 0.01) carrying two hinged poles of length 0.6 (capsules of radius 0.045), joint
damping 0.05, a motor on the slider with gear 500 and ctrlrange ±1, RK4 with timestep
0.01 s and frame_skip 5 (dt = 0.05 s), gravity (1e-5, 0, -9.81), no contacts.

State q = (x, θ₁, θ₂), q̇ = (ẋ, θ̇₁, θ̇₂); (x_tip, y_tip) are the x and z coordinates of the
tip site; f_c = qfrc_constraint[0] is the slider's constraint (joint-limit) force.

    obs        = (x, sin θ₁, sin θ₂, cos θ₁, cos θ₂, clip(q̇, ±10), clip(f_c, ±10)) ∈ R⁹
    terminated = y_tip ≤ 1  ∨  obs not finite  ∨  action not finite
    reward     = h·[¬terminated] − (0.01 x_tip² + (y_tip − 2)²) − (1e-3 θ̇₁² + 5e-3 θ̇₂²)

with h = ``healthy_reward`` (default 10), all quantities taken after the step.
Reset: q ~ U(−s, s)³, q̇ ~ N(0, s²)³ (s = ``reset_noise_scale``, default 0.1).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from envs import _validate
from envs.mjx_env import MjxEnv
from envs.types import EnvState

DOUBLE_PENDULUM_XML = """
<mujoco model="inverted_double_pendulum">
  <compiler inertiafromgeom="true"/>
  <default>
    <joint damping="0.05"/>
    <geom contype="0" friction="1 0.1 0.1"/>
  </default>
  <option gravity="1e-5 0 -9.81" integrator="RK4" timestep="0.01"/>
  <worldbody>
    <geom name="floor" type="plane" pos="0 0 -3.0" size="40 40 40"/>
    <geom name="rail" type="capsule" pos="0 0 0" quat="0.707 0 0.707 0" size="0.02 1"/>
    <body name="cart" pos="0 0 0">
      <joint name="slider" type="slide" axis="1 0 0" pos="0 0 0" limited="true" margin="0.01"
             range="-1 1"/>
      <geom name="cart" type="capsule" pos="0 0 0" quat="0.707 0 0.707 0" size="0.1 0.1"/>
      <body name="pole" pos="0 0 0">
        <joint name="hinge" type="hinge" axis="0 1 0" pos="0 0 0"/>
        <geom name="cpole" type="capsule" fromto="0 0 0 0 0 0.6" size="0.045 0.3"/>
        <body name="pole2" pos="0 0 0.6">
          <joint name="hinge2" type="hinge" axis="0 1 0" pos="0 0 0"/>
          <geom name="cpole2" type="capsule" fromto="0 0 0 0 0 0.6" size="0.045 0.3"/>
          <site name="tip" pos="0 0 .6" size="0.01 0.01"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="slide" joint="slider" gear="500" ctrllimited="true" ctrlrange="-1 1"/>
  </actuator>
</mujoco>
"""


class InvertedDoublePendulum(MjxEnv):
    """MJX port of Gymnasium's InvertedDoublePendulum-v5 (see the module docstring)."""

    def __init__(
        self,
        name: str = "InvertedDoublePendulum-v5",
        *,
        healthy_reward: float = 10.0,
        reset_noise_scale: float = 0.1,
        max_episode_steps: int = 1000,
    ):
        self._healthy_reward = _validate.finite_float("healthy_reward", healthy_reward)
        self._reset_noise_scale = _validate.finite_float(
            "reset_noise_scale", reset_noise_scale, 0.0
        )
        super().__init__(
            name,
            DOUBLE_PENDULUM_XML,
            frame_skip=5,
            observation_size=9,
            action_low=-np.ones(1, np.float32),
            action_high=np.ones(1, np.float32),
            max_episode_steps=_validate.positive_int("max_episode_steps", max_episode_steps),
        )

    @staticmethod
    def _observe(data) -> jax.Array:
        """(9,) observation of ``data`` (before the float32 cast)."""
        angles = data.qpos[1:]
        return jnp.concatenate(
            [
                data.qpos[:1],
                jnp.sin(angles),
                jnp.cos(angles),
                jnp.clip(data.qvel, -10, 10),
                jnp.clip(data.qfrc_constraint[:1], -10, 10),
            ]
        )

    def reset(self, key: jax.Array) -> EnvState:
        """q ~ U(−s, s)³, q̇ ~ N(0, s²)³; obs of that state; key: PRNG key."""
        key_q, key_v = jax.random.split(key)
        s = self._reset_noise_scale
        qpos = self._uniform_noise(key_q, 3, s)
        qvel = s * jax.random.normal(key_v, (3,), qpos.dtype)
        data = self._data_at(qpos, qvel)
        return self._initial_state(self._observe(data), data)

    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        """One step of dt = 0.05 s; action (1,) (see the module docstring for the rules)."""
        action, finite = self._sanitize_action(action)
        data = self._simulate(state.data, action)
        obs = self._observe(data)
        x_tip, _, y_tip = data.site_xpos[0]
        terminated = (y_tip <= 1) | ~jnp.all(jnp.isfinite(obs)) | ~finite
        distance_penalty = 0.01 * x_tip**2 + (y_tip - 2) ** 2
        velocity_penalty = 1e-3 * data.qvel[1] ** 2 + 5e-3 * data.qvel[2] ** 2
        reward = (
            jnp.where(terminated, 0.0, self._healthy_reward) - distance_penalty - velocity_penalty
        )
        return self._next_state(state, obs, reward, terminated, data)
