"""Replay buffer: wrap-around, the sampling range and dtypes, capacity rules."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sac_jax import replay_buffer as rb
from sac_jax.replay_buffer import Transition


def _batch(start, n, obs_size=3):
    """n transitions whose every field encodes its global index start..start+n-1."""
    i = jnp.arange(start, start + n, dtype=jnp.float32)
    return Transition(obs=jnp.repeat(i[:, None], obs_size, 1), action=i[:, None] * 0.5,
                      reward=i, next_obs=jnp.repeat(i[:, None], obs_size, 1) + 1,
                      terminated=(i % 2 == 0).astype(jnp.float32))


def _empty(capacity):
    example = jax.tree_util.tree_map(lambda x: x[0], _batch(0, 1))
    return rb.init(capacity, example)


def test_init_shapes_and_dtypes():
    buffer = _empty(8)
    assert buffer.capacity == 8
    assert buffer.data.obs.shape == (8, 3) and buffer.data.action.shape == (8, 1)
    assert buffer.data.reward.shape == (8,) and buffer.data.terminated.dtype == jnp.float32
    assert int(buffer.size) == 0 and int(buffer.position) == 0


def test_add_fills_then_wraps_around_overwriting_the_oldest():
    buffer = _empty(8)
    add = jax.jit(rb.add)
    for step in range(5):  # 5 batches of 2 = 10 transitions into 8 slots
        buffer = add(buffer, _batch(2 * step, 2))
    assert int(buffer.size) == 8
    assert int(buffer.position) == 10 % 8
    # slots 0, 1 hold transitions 8, 9; slots 2..7 hold 2..7
    np.testing.assert_array_equal(buffer.data.reward, [8, 9, 2, 3, 4, 5, 6, 7])
    np.testing.assert_array_equal(buffer.data.next_obs[:, 0], buffer.data.reward + 1)


def test_add_rejects_a_batch_that_does_not_divide_the_capacity():
    with pytest.raises(ValueError, match="not a multiple"):
        rb.add(_empty(8), _batch(0, 3))


def test_sample_draws_only_from_the_filled_part_uniformly():
    buffer = rb.add(_empty(100), _batch(0, 10))  # 10 of 100 slots filled
    batch = jax.jit(rb.sample, static_argnums=2)(buffer, jax.random.key(0), 20_000)
    rewards = np.asarray(batch.reward)
    assert rewards.min() == 0 and rewards.max() == 9  # never an empty slot
    counts = np.bincount(rewards.astype(int), minlength=10)
    # uniform over 10 slots: each count ~ Binomial(20000, 0.1), sd ~ 42
    assert np.all(np.abs(counts - 2000) < 250), counts
    # a sampled transition stays consistent across fields
    np.testing.assert_array_equal(batch.obs[:, 0], batch.reward)
    np.testing.assert_array_equal(batch.action[:, 0], batch.reward * 0.5)
    assert batch.obs.dtype == jnp.float32 and batch.terminated.dtype == jnp.float32


def test_sample_with_a_batch_shape_of_several_minibatches():
    buffer = rb.add(_empty(16), _batch(0, 16))
    batch = rb.sample(buffer, jax.random.key(1), (4, 32))
    assert batch.obs.shape == (4, 32, 3) and batch.reward.shape == (4, 32)


def test_gather_reads_the_given_slots_and_sample_is_gather_at_sample_indices():
    buffer = rb.add(_empty(16), _batch(0, 16))
    slots = jnp.array([[3, 3], [15, 0]])
    np.testing.assert_array_equal(rb.gather(buffer, slots).reward, [[3, 3], [15, 0]])
    key = jax.random.key(2)
    np.testing.assert_array_equal(
        rb.sample(buffer, key, (4, 8)).obs,
        rb.gather(buffer, rb.sample_indices(key, buffer.size, (4, 8))).obs)
