"""make_train on a small Pendulum-v1 run (pure JAX, quick to compile): output shapes and
values, determinism, and vmap over seeds equal to separate runs."""

import jax
import numpy as np
import pytest

import sac_jax

CONFIG = sac_jax.PRESETS["pendulum"].replace(
    total_steps=1024, learning_starts=256, eval_every=256, batch_size=64, num_envs=2,
    updates_per_step=2, actor_hidden=(32, 32), critic_hidden=(32, 32), eval_episodes=2)
KEYS = jax.random.split(jax.random.key(3), 2)


@pytest.fixture(scope="module")
def train():
    return jax.jit(sac_jax.make_train(CONFIG))


@pytest.fixture(scope="module")
def first(train):
    return jax.device_get(train(KEYS[0]))


def test_metrics_have_one_entry_per_evaluation(first):
    runner, metrics = first
    assert CONFIG.num_evals == 3
    np.testing.assert_array_equal(metrics["env_steps"], [512, 768, 1024])
    for name in ("eval_return", "train_return", "critic_loss", "actor_loss", "alpha", "q"):
        assert metrics[name].shape == (3,) and np.all(np.isfinite(metrics[name])), name
    assert np.all(np.isnan(metrics["value_loss"]))  # v2 has no value network
    # every iteration wrote num_envs transitions; 2 updates per training iteration
    assert int(runner.buffer.size) == 1024
    assert int(runner.sac.step) == (1024 - 256) // 2 * 2


def test_same_key_gives_identical_results(train, first):
    again = jax.device_get(train(KEYS[0]))
    jax.tree_util.tree_map(np.testing.assert_array_equal, first, again)


def test_vmap_over_seeds_equals_separate_runs(train, first):
    """Two seeds in one vmapped program reproduce two separate runs (float32: vmap batches
    the matmuls, so equality is to rounding: rtol 1e-4 on metrics and parameters)."""
    batched = jax.device_get(jax.jit(jax.vmap(sac_jax.make_train(CONFIG)))(KEYS))
    second = jax.device_get(train(KEYS[1]))
    for seed, single in enumerate((first, second)):
        runner, metrics = single
        for name in metrics:
            np.testing.assert_allclose(batched[1][name][seed], metrics[name], rtol=1e-4,
                                       atol=1e-5, err_msg=name)
        jax.tree_util.tree_map(
            lambda b, s: np.testing.assert_allclose(b[seed], s, rtol=1e-4, atol=1e-5),
            batched[0].sac.actor_params, runner.sac.actor_params)
    assert not np.allclose(first[1]["critic_loss"], second[1]["critic_loss"])
