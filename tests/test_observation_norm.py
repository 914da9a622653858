"""Observation normalisation (`SACConfig.normalize_observations`, `sac_jax.observation_norm`):
the running statistics against numpy, every network fed normalised observations with no
gradient into the statistics, for SAC v2 and v1, and a run that keeps them in its actors."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sac_jax
from sac_jax import SACConfig, Transition, observation_norm
from sac_jax.observation_norm import COLLECTION
from tests.pendulum_shapes import pendulum_agent

CONFIG = SACConfig(env="Pendulum-v1", actor_hidden=(32, 32), critic_hidden=(32, 32),
                   batch_size=16, learning_starts=16, eval_every=16, total_steps=48)
B = CONFIG.batch_size


def test_the_running_statistics_are_those_of_all_observations_so_far():
    """Batches of 1, 7 and 40 observations, on one device and as 4 equal data-parallel shares
    (`vmap` with an axis name: the statistics of the whole batch on every share)."""
    rng = np.random.default_rng(0)
    seen = [rng.normal([3.0, -1.0], [0.5, 20.0], (n, 2)).astype(np.float32) for n in (1, 7, 40)]
    stats = observation_norm.init(2)
    np.testing.assert_array_equal(observation_norm.std(stats), 1.0)
    sharded = jax.vmap(lambda s, x: observation_norm.update(s, x, "d"), in_axes=(None, 0),
                       axis_name="d")
    shares = observation_norm.init(2)
    for batch in seen:
        stats = observation_norm.update(stats, jnp.asarray(batch))
        if len(batch) % 4 == 0:
            shares = jax.tree_util.tree_map(lambda x: x[0], sharded(shares, batch.reshape(4, -1, 2)))
        else:
            shares = observation_norm.update(shares, jnp.asarray(batch))
    every = np.concatenate(seen)
    for s in (stats, shares):
        assert float(s["count"]) == len(every)
        np.testing.assert_allclose(s["mean"], every.mean(0), rtol=1e-5)
        np.testing.assert_allclose(observation_norm.std(s), every.std(0), rtol=1e-4)
    obs = jnp.asarray(every[:3])
    np.testing.assert_allclose(observation_norm.apply(stats, obs),
                               (every[:3] - every.mean(0)) / every.std(0), rtol=1e-4, atol=1e-5)


_agent = pendulum_agent


@pytest.mark.parametrize("variant", ["v2", "v1"])
def test_every_network_sees_normalised_observations_and_no_gradient_reaches_the_statistics(
        variant):
    """An update of an agent with statistics (mean m, std s) on raw observations is the update
    of the same parameters without normalisation on (obs - m) / s: critics, value network,
    actor and temperature alike; the statistics come out unchanged (Adam's step on their zero
    gradient), and the deterministic action on raw observations matches too."""
    config = CONFIG.replace(variant=variant) if variant == "v2" else sac_jax.PRESETS["v1"].replace(
        env="Pendulum-v1", actor_hidden=(32, 32), critic_hidden=(32, 32), batch_size=B)
    plain, normed = _agent(config), _agent(config.replace(normalize_observations=True))
    k = jax.random.split(jax.random.key(1), 5)
    mean, std = jnp.array([0.5, -2.0, 3.0]), jnp.array([0.1, 4.0, 2.0])
    raw = Transition(obs=mean + std * jax.random.normal(k[0], (B, 3)),
                     action=jax.random.uniform(k[1], (B, 1), minval=-2, maxval=2),
                     reward=jax.random.normal(k[2], (B,)),
                     next_obs=mean + std * jax.random.normal(k[3], (B, 3)),
                     terminated=(jnp.arange(B) % 5 == 0).astype(jnp.float32))
    stats = {"count": jnp.float32(10.0), "mean": mean, "m2": 10.0 * std ** 2}
    state = normed.init(jax.random.key(2))
    state = state.replace(actor_params={**state.actor_params, COLLECTION: stats})
    state = state.replace(actor_opt_state=normed.actor_optimizer.init(state.actor_params))
    base = plain.init(jax.random.key(2))
    scaled = raw.replace(obs=(raw.obs - mean) / std, next_obs=(raw.next_obs - mean) / std)
    after, metrics = jax.jit(sac_jax.sac_update)(normed, state, raw, k[4])
    expected, expected_metrics = jax.jit(sac_jax.sac_update)(plain, base, scaled, k[4])
    _close = lambda a, b: jax.tree_util.tree_map(
        lambda x, y: np.testing.assert_allclose(x, y, rtol=2e-5, atol=1e-6), a, b)
    for field in ("critic_params", "critic_target_params", "value_params", "log_alpha"):
        _close(getattr(after, field), getattr(expected, field))
    params = {k_: v for k_, v in after.actor_params.items() if k_ != COLLECTION}
    _close(params, expected.actor_params)
    _close(after.actor_params[COLLECTION], stats)
    _close(metrics, expected_metrics)
    _close(normed.act(after.actor_params, raw.obs), plain.act(expected.actor_params, scaled.obs))


def test_a_run_keeps_the_statistics_of_every_observation_acted_on_in_its_actors():
    """4 environments x 12 iterations: 48 observations counted, in the last actor; the
    delivered actor (which takes raw observations) holds the statistics of the observations
    acted on up to the point it was kept at."""
    config = CONFIG.replace(num_envs=4, normalize_observations=True)
    runner, metrics = jax.jit(sac_jax.make_train(config))(jax.random.key(0))
    stats = runner.sac.actor_params[COLLECTION]
    assert float(stats["count"]) == config.total_steps
    assert np.all(np.asarray(observation_norm.std(stats)) > 0.05)
    kept = runner.delivered.actor_params[COLLECTION]
    assert 0 < int(runner.delivered.env_steps) and (
        float(kept["count"]) == int(runner.delivered.env_steps))
    assert np.all(np.asarray(observation_norm.std(kept)) > 0.05)
    assert np.all(np.isfinite(np.asarray(metrics["eval_return"])))
