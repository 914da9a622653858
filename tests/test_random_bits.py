"""Draws from one Threefry hash (`sac_jax.random_bits`, `sac_jax.randomness.FromKeys`): the
numbers `jax.random` makes from the same bits, and one hash per acting and learning step."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sac_jax
from sac_jax import SACConfig
from sac_jax.random_bits import index_from_bits, normal_from_bits, uniform_from_bits
from sac_jax.randomness import FromKeys
from tests.pendulum_shapes import pendulum_agent

SHAPE = (64, 3)


def _bits(key, shape=SHAPE):
    return jax.random.bits(key, shape, jnp.uint32)


def test_uniform_and_normal_are_jax_randoms_of_the_same_bits():
    key = jax.random.key(7)
    low, high = jnp.array([-2.0, 0.0, 1.0]), jnp.array([2.0, 0.5, 3.0])
    np.testing.assert_array_equal(uniform_from_bits(_bits(key), low, high),
                                  jax.random.uniform(key, SHAPE, minval=low, maxval=high))
    np.testing.assert_array_equal(normal_from_bits(_bits(key)), jax.random.normal(key, SHAPE))


@pytest.mark.parametrize("size", [0, 1, 3, 1000, 10_000_000])
def test_slots_are_jax_randint_of_the_same_two_draws(size):
    """randint hashes the two halves of a split key; the same words give the same slots, in
    [0, max(size, 1))."""
    key = jax.random.key(3)
    k1, k2 = jax.random.split(key)
    slots = index_from_bits(jnp.stack([_bits(k1), _bits(k2)]), jnp.int32(size))
    np.testing.assert_array_equal(slots, jax.random.randint(key, SHAPE, 0, max(size, 1)))
    assert slots.dtype == jnp.int32 and 0 <= int(slots.min()) and int(slots.max()) < max(size, 1)


@pytest.mark.parametrize("order,names", [
    (("critic", "actor"), ["actor", "critic", "temperature"]),
    (("critic", "value", "actor"), ["actor", "critic", "temperature", "value"])])
def test_sample_noise_draws_what_the_update_reads(order, names):
    config = SACConfig(env="Pendulum-v1", variant="v1" if "value" in order else "v2",
                       update_order=order, policy_frequency=2, learn_alpha="value" not in order)
    agent = pendulum_agent(config)
    noise = sac_jax.sample_noise(agent, jax.random.key(0), 16)
    assert sorted(noise) == names
    assert noise["critic"].shape == (16, 1) and noise["actor"].shape == (2, 16, 1)
    words = np.concatenate([np.ravel(noise[n]) for n in noise])
    assert len(np.unique(words)) == len(words)  # no two entries share their numbers


def _hashes(fn, *args):
    """How many Threefry hashes (bits, splits, fold-ins) the jaxpr of fn(*args) makes."""
    text = str(jax.make_jaxpr(fn)(*args))
    return sum(text.count(f"{op}[") for op in ("random_bits", "random_split", "random_fold_in"))


def test_from_keys_hashes_once_per_method_and_draws_the_documented_shapes():
    config = SACConfig(env="Pendulum-v1", batch_size=16)
    agent = pendulum_agent(config)
    source = FromKeys(agent, num_envs=4, updates=3, batch_size=16)
    key, size, i = jax.random.key(0), jnp.int32(40), jnp.int32(0)
    assert _hashes(source.acting, key, i) == 1
    assert _hashes(source.learning, key, size, i) == 1
    random_action, noise = source.acting(key, i)
    assert random_action.shape == noise.shape == (4, 1)
    assert float(jnp.min(random_action)) >= -2.0 and float(jnp.max(random_action)) <= 2.0
    slots, update_noise = source.learning(key, size, i)
    assert slots.shape == (3, 16) and int(slots.max()) < 40
    assert update_noise["critic"].shape == (3, 16, 1)
    assert update_noise["actor"].shape == (3, 1, 16, 1)
    # each update its own noise
    assert not np.array_equal(update_noise["critic"][0], update_noise["critic"][1])
