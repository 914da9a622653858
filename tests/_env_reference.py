"""Shared helpers of the environment tests: closed-loop rollouts of our environments (one
jitted ``lax.scan`` per environment object) and of Gymnasium's C-MuJoCo counterparts.

Both sides apply ``a_t = on_t · (K · z_t) + n_t`` where z_t = (q, q̇) is that side's own
physics state, K a fixed linear stabilising gain and n_t a shared noise sequence that
includes out-of-bound values.  The feedback matters: replaying one action sequence
open-loop on an unstable pendulum amplifies rounding differences like e^{λt} (λ ≈ 5/s),
so open-loop trajectories separate after ~60 steps whatever the implementation; the
feedback uses the full-precision state (not the float32 observation) so that the float64
comparison is not limited by float32 quantisation of the controller input.  With on_t = 0 after
step 250 and a constant push, the episodes terminate, which checks the termination step.
"""

from __future__ import annotations

import gymnasium as gym
import jax
import jax.numpy as jnp
import numpy as np

import envs

T = 300  # rollout length (one compiled scan per environment)
STABILISE = 250  # steps under feedback before the push

# gain K on (q, q̇), noise std, rate of ±2×bound kicks, push after STABILISE, Gymnasium id.
# The double pendulum does not survive a full-force step, so its out-of-bound actions come
# in the push phase only (1.5 > bound 1).
CASES = {
    "InvertedPendulum-v5": ([1.0, 20.0, 1.0, 2.0], 0.3, 0.04, 3.0, "InvertedPendulum-v5"),
    "InvertedPendulum-v4": ([1.0, 20.0, 1.0, 2.0], 0.3, 0.04, 3.0, "InvertedPendulum-v4"),
    "InvertedPendulumBullet-v0": (
        [1 / 3, 20 / 3, 1 / 3, 2 / 3], 0.1, 0.04, 1.0, "InvertedPendulum-v5"),
    "InvertedDoublePendulum-v5": (
        [-0.213, -1.813, -5.569, -0.315, -0.902, -0.848], 0.05, 0.0, 1.5,
        "InvertedDoublePendulum-v5"),
    "Pendulum-v1": ([0.0, 0.0], 1.5, 0.04, 0.0, "Pendulum-v1"),
}


def inputs(env: envs.Env, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(gain (2 nq,), on (T,), noise (T, 1)) float32 inputs of the closed-loop rollouts."""
    gain, std, kick_rate, push, _ = CASES[env.name]
    bound = float(env.action_high[0])
    rng = np.random.default_rng(seed)
    on = np.ones(T, np.float32)
    on[STABILISE:] = 0.0
    noise = rng.normal(0.0, std, (T, 1))
    kicks = rng.random(T) < kick_rate
    noise[kicks, 0] = 2 * bound * rng.choice([-1.0, 1.0], kicks.sum())
    noise[STABILISE:] += push
    return np.asarray(gain, np.float32), on, noise.astype(np.float32)


def make_rollout(env: envs.Env):
    """jit of (key, step_count0, gain, on, noise) -> (s0, states with leading axis T).

    s0 = env.reset(key) with step_count replaced by step_count0; then T closed-loop steps.
    """

    def rollout(key, step_count0, gain, on, noise):
        s0 = env.reset(key).replace(step_count=step_count0)

        def body(state, x):
            on_t, noise_t = x
            action = on_t * jnp.dot(gain, physics_state(state.data)) + noise_t
            state = env.step(state, action)
            return state, state

        _, states = jax.lax.scan(body, s0, (on, noise))
        return s0, states

    return jax.jit(rollout)


def bullet_obs(o: np.ndarray) -> np.ndarray:
    """Map InvertedPendulum-v5's (x, θ, ẋ, θ̇) to the Bullet variant's (x, ẋ, cos θ, sin θ, θ̇)."""
    return np.array([o[0], o[2], np.cos(o[1]), np.sin(o[1]), o[3]])


def physics_state(data) -> jax.Array:
    """(..., 2 nq) physics state (q, q̇) of our ``EnvState.data``, in its own float dtype."""
    if hasattr(data, "theta"):
        return jnp.stack([data.theta, data.theta_dot], axis=-1)
    return jnp.concatenate([data.qpos, data.qvel], axis=-1)


def gym_rollout(
    name: str, s0: envs.EnvState, gain, on, noise, dtype=np.float32
) -> dict[str, np.ndarray]:
    """Gymnasium's env from our initial state s0, same controller and noise, until done.

    Actions are rounded to ``dtype`` (that of our side).  Returns obs0, and per step obs,
    reward, terminated, truncated and the physics state (q, q̇) after the step.
    """
    gym_id = CASES[name][-1]
    env = gym.make(gym_id)
    env.reset(seed=0)
    raw = env.unwrapped
    if name == "Pendulum-v1":
        raw.state = np.array([s0.data.theta, s0.data.theta_dot], np.float64)
    else:
        raw.set_state(np.asarray(s0.data.qpos, np.float64), np.asarray(s0.data.qvel, np.float64))
    bullet = name == "InvertedPendulumBullet-v0"

    def gym_state() -> np.ndarray:
        if name == "Pendulum-v1":
            return np.array(raw.state)
        return np.concatenate([raw.data.qpos, raw.data.qvel])

    obs, state = raw._get_obs(), gym_state()
    obs = bullet_obs(obs) if bullet else obs
    out = {"obs0": obs, "obs": [], "reward": [], "terminated": [], "truncated": [], "state": []}
    for t in range(T):
        action = (on[t] * np.dot(np.float64(gain), state) + noise[t]).astype(dtype)
        if bullet:
            action = dtype(3.0) * np.clip(action, dtype(-1), dtype(1))
        obs, reward, terminated, truncated, _ = env.step(action)
        obs = bullet_obs(obs) if bullet else obs
        state = gym_state()
        for k, v in (("obs", obs), ("reward", reward), ("terminated", terminated),
                     ("truncated", truncated), ("state", state)):
            out[k].append(v)
        if terminated or truncated:
            break
    return {k: np.asarray(v) for k, v in out.items()}
