"""Pendulum-v1's shapes (3 observations, 1 action in [-2, 2]) for the tests of the updates
(test_updates, test_observation_norm, parallel_checks): an agent, a random batch, and a tree
cast to another float dtype."""

import jax
import jax.numpy as jnp

import sac_jax


def pendulum_agent(config: sac_jax.SACConfig) -> sac_jax.Agent:
    """`config`'s agent for Pendulum-v1's shapes, without building the environment."""
    return sac_jax.make_agent(config, observation_size=3, action_size=1, action_low=-2.0,
                              action_high=2.0)


def pendulum_batch(key: jax.Array, batch_size: int) -> sac_jax.Transition:
    """A random batch of `batch_size` transitions, every fifth one terminal."""
    k = jax.random.split(key, 4)
    return sac_jax.Transition(
        obs=jax.random.normal(k[0], (batch_size, 3)),
        action=jax.random.uniform(k[1], (batch_size, 1), minval=-2, maxval=2),
        reward=jax.random.normal(k[2], (batch_size,)),
        next_obs=jax.random.normal(k[3], (batch_size, 3)),
        terminated=(jnp.arange(batch_size) % 5 == 0).astype(jnp.float32))


def cast_floats(tree, dtype):
    """`tree` with every floating leaf cast to `dtype` (float64 needs JAX_ENABLE_X64=1)."""
    return jax.tree_util.tree_map(
        lambda x: x.astype(dtype) if jnp.issubdtype(x.dtype, jnp.floating) else x, tree)
