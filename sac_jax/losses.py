"""The SAC objectives as pure functions of arrays (notation of Haarnoja et al. 2018a/b).

B is the batch size, N the number of critics. Each loss is a mean over the batch; targets are
constants (callers pass them through `jax.lax.stop_gradient`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def soft_q_target(reward: jax.Array, terminated: jax.Array, next_value: jax.Array,
                  gamma: float, reward_scale: float = 1.0) -> jax.Array:
    """Q-hat(s, a) = c r + gamma (1 - d) V(s'), all of shape (B,).

    v2: V(s') = min_j Q-bar_j(s', a') - alpha log pi(a'|s'), a' ~ pi(.|s').
    v1: V(s') = V-bar(s'), the target value network.
    d is `terminated` only: a truncated episode still bootstraps.
    Computed in the common dtype of the three arrays: with float64 networks and a float32
    replay buffer, c and gamma are not rounded to float32.
    """
    dtype = jnp.result_type(reward, terminated, next_value)
    reward, terminated = reward.astype(dtype), terminated.astype(dtype)
    return reward_scale * reward + (1.0 - terminated) * gamma * next_value


def critic_loss(q: jax.Array, target: jax.Array, coef: float = 1.0) -> jax.Array:
    """J_Q(theta) = sum_i coef * mean_b (Q_i(s_b, a_b) - Q-hat_b)^2, with q (N, B), target (B,).

    coef = 1 is PyTorch's MSE per critic summed (seeds 001, 002); 0.5 the paper's (seed 000).
    """
    return coef * jnp.sum(jnp.mean((q - target) ** 2, axis=-1))


def actor_loss(log_prob: jax.Array, q_min: jax.Array, alpha: jax.Array) -> jax.Array:
    """J_pi(phi) = mean_b [alpha log pi(a~_b|s_b) - min_i Q_i(s_b, a~_b)], a~ = f_phi(eps; s),
    log_prob and q_min of shape (B,)."""
    return jnp.mean(alpha * log_prob - q_min)


def temperature_loss(log_alpha: jax.Array, log_prob: jax.Array, target_entropy: float,
                     form: str = "alpha") -> jax.Array:
    """J_alpha = mean_b [-alpha (log pi(a_b|s_b) + H-bar)] with log_prob (B,) held constant.

    form "alpha" differentiates alpha = exp(log alpha) (CleanRL, seed 002); form "log_alpha"
    puts log alpha in place of alpha (seed 001). Both share the sign of the gradient.
    """
    weight = jnp.exp(log_alpha) if form == "alpha" else log_alpha
    return jnp.mean(-weight * (log_prob + target_entropy))


def value_loss(v: jax.Array, target: jax.Array, coef: float = 1.0) -> jax.Array:
    """J_V(psi) = coef * mean_b (V_psi(s_b) - [min_i Q_i(s_b, a~_b) - alpha log pi(a~_b|s_b)])^2,
    a~ ~ pi(.|s) freshly sampled, v and target (B,)."""
    return coef * jnp.mean((v - target) ** 2)
