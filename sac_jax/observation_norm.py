"""Observation normalisation (`SACConfig.normalize_observations`, as Brax's and MuJoCo
Playground's SAC use it): the networks see (s - mean) / std, with the running mean and standard
deviation of every observation the run's environments have produced so far.

The statistics live in the actor's variables, in the collection `COLLECTION` beside "params":
(count n, mean (O,), m2 (O,), the sum of squared deviations), so a delivered or saved actor
takes raw observations and normalises them itself. The critics and the value network get
observations normalised with the same statistics (`normalize(actor_params, obs)`). No gradient
reaches them (`jax.lax.stop_gradient`: Adam's step on a zero gradient is exactly zero); they
change only through `observe`, once per iteration, with the observations the actions were
taken from. The replay buffer keeps raw observations, normalised when sampled, with the current
statistics.

In float32 (the parameters' dtype) the statistics stop moving once a batch is too small a
part of what came before: n stays at 2^24 for batches of one observation (2^32 for 256), and m2
likewise once n / n_b passes 2^24, so a run of one environment past 16.8M steps keeps the
statistics it had there (as Brax's running statistics, also float32, do).
"""

from __future__ import annotations

from typing import Optional

import jax
import jax.numpy as jnp

COLLECTION = "observations"
"""The flax variable collection holding the statistics."""
MIN_STD = 1e-6
"""std = max(sqrt(m2 / n), MIN_STD) (Brax's `running_statistics` floor); 1 before any data."""


def init(size: int, dtype=jnp.float32) -> dict:
    """No observations yet: n = 0, mean 0, m2 0 (std 1)."""
    return {"count": jnp.zeros((), dtype), "mean": jnp.zeros((size,), dtype),
            "m2": jnp.zeros((size,), dtype)}


def std(stats: dict) -> jax.Array:
    """sqrt(m2 / n) floored at MIN_STD; ones while n = 0. Shape (O,)."""
    variance = stats["m2"] / jnp.maximum(stats["count"], 1.0)
    return jnp.where(stats["count"] > 0, jnp.maximum(jnp.sqrt(variance), MIN_STD), 1.0)


def apply(stats: dict, obs: jax.Array) -> jax.Array:
    """(obs - mean) / std for obs (..., O), no gradient into the statistics."""
    stats = jax.lax.stop_gradient(stats)
    return (obs - stats["mean"]) / std(stats)


def update(stats: dict, obs: jax.Array, axis: Optional[str] = None) -> dict:
    """The statistics after a batch obs (B, O) (Chan et al.'s parallel combination):
        delta = mean_b - mean,  n' = n + n_b,  mean' = mean + delta n_b / n',
        m2' = m2 + m2_b + delta^2 n n_b / n'.
    With a data-parallel `axis`, the batch is every device's (equal shares), so the statistics
    stay identical on all devices."""
    obs = obs.astype(stats["mean"].dtype)
    n_b = jnp.asarray(obs.shape[0], obs.dtype)
    mean_b = jnp.mean(obs, axis=0)
    if axis is not None:
        mean_b, n_b = jax.lax.pmean(mean_b, axis), jax.lax.psum(n_b, axis)
    m2_b = jnp.sum((obs - mean_b) ** 2, axis=0)
    if axis is not None:
        m2_b = jax.lax.psum(m2_b, axis)
    n = stats["count"] + n_b
    delta = mean_b - stats["mean"]
    return {"count": n, "mean": stats["mean"] + delta * n_b / n,
            "m2": stats["m2"] + m2_b + delta ** 2 * stats["count"] * n_b / n}


def normalize(actor_params, obs: jax.Array) -> jax.Array:
    """obs normalised with the statistics of `actor_params` (unchanged where it has none: a
    run without `normalize_observations`)."""
    if COLLECTION not in actor_params:
        return obs
    return apply(actor_params[COLLECTION], obs)


def observe(actor_params, obs: jax.Array, axis: Optional[str] = None):
    """`actor_params` with its statistics updated by obs (B, O) (`update`)."""
    return {**actor_params, COLLECTION: update(actor_params[COLLECTION], obs, axis)}
