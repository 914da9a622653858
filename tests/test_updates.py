"""The pure updates: randomness by key or injected noise, determinism, policy delay, Polyak,
the temperature step, and the SAC v1 path. Small networks on Pendulum-v1 shapes."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sac_jax
from sac_jax import SACConfig
from tests.pendulum_shapes import pendulum_agent, pendulum_batch

CONFIG = SACConfig(env="Pendulum-v1", actor_hidden=(32, 32), critic_hidden=(32, 32),
                   batch_size=16, learning_starts=16, eval_every=16, total_steps=48)
B = CONFIG.batch_size


_agent = pendulum_agent


def _batch(seed=0):
    return pendulum_batch(jax.random.key(seed), B)


def _allclose(a, b, **kw):
    jax.tree_util.tree_map(lambda x, y: np.testing.assert_allclose(x, y, **kw), a, b)


def _changed(a, b):
    return any(bool(jnp.any(x != y)) for x, y in
               zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b)))


update = jax.jit(sac_jax.sac_update)


def test_key_and_the_noise_it_draws_give_the_same_update():
    """A key draws `sample_noise(agent, key, B)` and updates with it: the update by key and the
    update by that noise drawn in the same program trace to the same jaxpr, so they are one
    program and agree bit for bit (bit-exact by construction). With the noise drawn by a
    separate program and passed in, the update is another compiled program, whose fusions may
    round differently (a 1-ulp difference in a metric with SSE4.2 code), so that pair is not
    compared bit for bit."""
    agent = _agent(CONFIG)
    state = agent.init(jax.random.key(0))
    key = jax.random.key(7)
    by_key = lambda s, b, k: sac_jax.sac_update(agent, s, b, k)
    by_noise = lambda s, b, k: sac_jax.sac_update(agent, s, b, sac_jax.sample_noise(agent, k, B))
    args = (state, _batch(), key)
    assert str(jax.make_jaxpr(by_key)(*args)) == str(jax.make_jaxpr(by_noise)(*args))
    _allclose(jax.jit(by_key)(*args), jax.jit(by_noise)(*args), rtol=0, atol=0)


def test_same_key_same_result_and_different_keys_differ():
    agent = _agent(CONFIG)
    state = agent.init(jax.random.key(0))
    a = update(agent, state, _batch(), jax.random.key(1))
    b = update(agent, state, _batch(), jax.random.key(1))
    c = update(agent, state, _batch(), jax.random.key(2))
    _allclose(a, b, rtol=0, atol=0)
    assert _changed(a[0].actor_params, c[0].actor_params)


def test_update_changes_each_part_and_counts_steps():
    agent = _agent(CONFIG)
    state = agent.init(jax.random.key(0))
    new, metrics = update(agent, state, _batch(), jax.random.key(1))
    assert int(new.step) == 1
    for name in ("actor_params", "critic_params", "critic_target_params", "log_alpha"):
        assert _changed(getattr(state, name), getattr(new, name)), name
    assert float(new.alpha) == pytest.approx(float(jnp.exp(new.log_alpha)))
    assert set(metrics) >= {"critic_loss", "actor_loss", "alpha_loss", "alpha", "q", "entropy"}
    assert all(bool(jnp.isfinite(v)) for v in metrics.values())


def test_polyak_update_is_the_convex_combination():
    target, online = {"w": jnp.array([1.0, 2.0])}, {"w": jnp.array([3.0, -2.0])}
    out = sac_jax.polyak_update(target, online, 0.25)
    np.testing.assert_allclose(out["w"], [0.25 * 3 + 0.75 * 1, 0.25 * -2 + 0.75 * 2])


def test_critic_target_moves_by_tau():
    """One Polyak step in float32 against the same convex combination computed outside the
    program: two products and a sum, a few ulps apart at most (rtol 1e-6 = 8 ulps)."""
    agent = _agent(CONFIG)
    state = agent.init(jax.random.key(0))
    new, _ = update(agent, state, _batch(), jax.random.key(1))
    expected = sac_jax.polyak_update(state.critic_target_params, new.critic_params, CONFIG.tau)
    _allclose(new.critic_target_params, expected, rtol=1e-6, atol=1e-7)


def test_policy_delay_runs_k_actor_steps_every_kth_update():
    config = CONFIG.replace(policy_frequency=2)
    agent = _agent(config)
    state = agent.init(jax.random.key(0))
    first, m1 = update(agent, state, _batch(), jax.random.key(1))
    assert not _changed(state.actor_params, first.actor_params)
    assert bool(jnp.isnan(m1["actor_loss"])) and float(first.log_alpha) == float(state.log_alpha)
    second, m2 = update(agent, first, _batch(), jax.random.key(2))
    assert _changed(first.actor_params, second.actor_params)
    assert bool(jnp.isfinite(m2["actor_loss"]))
    # K = 2 Adam steps happened: the actor's optimiser count advanced by 2
    count = jax.tree_util.tree_leaves(second.actor_opt_state)[0]
    assert int(count) == 2


def test_target_update_period():
    config = CONFIG.replace(target_update_period=2)
    agent = _agent(config)
    state = agent.init(jax.random.key(0))
    first, _ = update(agent, state, _batch(), jax.random.key(1))
    assert not _changed(state.critic_target_params, first.critic_target_params)
    second, _ = update(agent, first, _batch(), jax.random.key(2))
    assert _changed(first.critic_target_params, second.critic_target_params)


def test_fixed_alpha_stays():
    agent = _agent(CONFIG.replace(learn_alpha=False, alpha_init=0.2))
    state = agent.init(jax.random.key(0))
    new, metrics = update(agent, state, _batch(), jax.random.key(1))
    assert float(new.alpha) == pytest.approx(0.2) and "alpha_loss" not in metrics


def test_temperature_gradient_sign():
    """Entropy below target (log pi > -H) must raise alpha; above target must lower it."""
    agent = _agent(CONFIG)
    state = agent.init(jax.random.key(0))
    up, _ = sac_jax.update_temperature(agent, state, jnp.full((B,), 5.0))
    down, _ = sac_jax.update_temperature(agent, state, jnp.full((B,), -5.0))
    assert float(up.alpha) > float(state.alpha) > float(down.alpha)


def test_v1_updates_value_and_its_target():
    config = CONFIG.replace(variant="v1", learn_alpha=False, reward_scale=2.0, loss_coef=0.5,
                            update_order=("value", "actor", "critic"))
    agent = _agent(config)
    state = agent.init(jax.random.key(0))
    assert state.critic_target_params is None and state.value_params is not None
    new, metrics = update(agent, state, _batch(), jax.random.key(1))
    assert _changed(state.value_params, new.value_params)
    expected = sac_jax.polyak_update(state.value_target_params, new.value_params, config.tau)
    _allclose(new.value_target_params, expected, rtol=1e-6, atol=1e-7)  # Polyak: a few ulps
    assert {"value_loss", "critic_loss", "actor_loss"} <= set(metrics)


def test_noise_of_the_wrong_shape_is_rejected():
    agent = _agent(CONFIG)
    state = agent.init(jax.random.key(0))
    with pytest.raises(ValueError, match="noise has shape"):
        sac_jax.update_actor(agent, state, _batch().obs, jnp.zeros((B + 1, 1)))


def test_noise_dict_of_the_wrong_shape_or_missing_an_entry_is_rejected():
    """A dict of noise holds K = policy_frequency actor steps' draws, (K, B, A): with 1 or 3
    of them for K = 2 the actor block would run 1 or 3 steps instead of 2."""
    config = CONFIG.replace(policy_frequency=2)
    agent = _agent(config)
    state = agent.init(jax.random.key(0))
    good = sac_jax.sample_noise(agent, jax.random.key(1), B)
    assert good["actor"].shape == (2, B, 1)
    sac_jax.sac_update(agent, state, _batch(), good)
    for k in (1, 3):
        bad = dict(good, actor=jnp.zeros((k, B, 1)))
        with pytest.raises(ValueError, match=rf'noise\["actor"\] has shape \({k}, {B}, 1\), '
                                             rf"expected \(2, {B}, 1\)"):
            sac_jax.sac_update(agent, state, _batch(), bad)
    with pytest.raises(ValueError, match='noise has no "temperature" entry'):
        sac_jax.sac_update(agent, state, _batch(), {n: good[n] for n in ("critic", "actor")})


def test_make_agent_rejects_bad_bounds():
    with pytest.raises(ValueError, match="action bounds"):
        sac_jax.make_agent(CONFIG, 3, 1, action_low=1.0, action_high=-1.0)
    with pytest.raises(ValueError, match=r"action_low has shape \(3,\), expected a scalar or "
                                         r"\(2,\) for action_size=2"):
        sac_jax.make_agent(CONFIG, 3, 2, action_low=[-1.0, -1.0, -1.0], action_high=1.0)
    with pytest.raises(ValueError, match=r"action_high has shape \(1, 2\)"):
        sac_jax.make_agent(CONFIG, 3, 2, action_low=-1.0, action_high=[[1.0, 1.0]])
