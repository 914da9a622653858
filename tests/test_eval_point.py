"""`sac_jax.eval_point`: a point's 2 E episodes in one batch (the evaluation's from the
point's key, as `sac_jax.evaluate` draws them, the confirmation's from another key, then the
same E again for the kept actor), the returns the selection sees (each actor's own), and the
depth of the evaluations under way with `eval_alongside`."""

import jax
import jax.numpy as jnp
import numpy as np

import sac_jax
from sac_jax import selection
from sac_jax.eval_point import EvalPoints
from sac_jax.evaluation import evaluate_from
from sac_jax.train import agent_for
from tests.test_eval_alongside import CONFIG  # Pendulum-v1, E = 7; D = 3, eval_alongside


def test_a_points_batch_is_the_evaluations_then_the_confirmations_then_both_again():
    _, env = agent_for(CONFIG)
    points, (key, k_confirm) = EvalPoints(CONFIG, env), jax.random.split(jax.random.key(5))
    obs = np.asarray(points.start(key, k_confirm).start.obs)
    e = CONFIG.eval_episodes + CONFIG.confirm_episodes
    assert points.episodes == e and obs.shape[0] == 2 * e
    evaluation = jax.vmap(env.reset)(jax.random.split(key, CONFIG.eval_episodes)).obs
    np.testing.assert_array_equal(obs[:CONFIG.eval_episodes], evaluation)
    confirmation = obs[CONFIG.eval_episodes:e]
    assert not np.isin(confirmation, evaluation).any()  # initial states no evaluation used
    fresh = jax.vmap(env.reset)(jax.random.split(k_confirm, CONFIG.confirm_episodes)).obs
    np.testing.assert_array_equal(confirmation, fresh)
    np.testing.assert_array_equal(obs[e:], obs[:e])  # the kept actor's: the same states


def test_the_selection_sees_each_actors_own_returns():
    """With a kept actor other than the point's, the point's evaluation return is what
    `sac_jax.evaluate` gives the point's actor from the same key, and the kept actor's return
    is its own on the confirmation's initial states."""
    agent, env = agent_for(CONFIG)
    points, (key, k_confirm) = EvalPoints(CONFIG, env), jax.random.split(jax.random.key(7))
    actor = agent.init(jax.random.key(0)).actor_params
    kept = selection.init(agent.init(jax.random.key(1)).actor_params)
    kept = kept.replace(score=jnp.float32(-1e9), count=jnp.int32(1))  # any candidate replaces
    delivered, (score, confirmed, kept_return), pending = jax.jit(
        lambda: points.evaluate(agent, actor, kept, None, key, k_confirm, jnp.int32(0),
                                jnp.int32(300)))()
    assert pending is None and points.depth == 0
    expected = sac_jax.evaluate(agent, env, actor, key, CONFIG.eval_episodes)
    np.testing.assert_allclose(score, np.mean(expected), rtol=1e-5)
    start = points.start(key, k_confirm).start
    confirm_states = jax.tree_util.tree_map(
        lambda x: x[CONFIG.eval_episodes:points.episodes], start)
    for params, value in ((actor, confirmed), (kept.actor_params, kept_return)):
        own = evaluate_from(agent, env, params, confirm_states)
        np.testing.assert_allclose(value, np.mean(own), rtol=1e-5)
    assert float(confirmed) != float(kept_return)
    replaced = float(confirmed) > float(kept_return)  # else the kept actor is re-measured
    assert int(delivered.env_steps) == (300 if replaced else -1)
    assert int(delivered.count) == (1 if replaced else 2)


def test_evaluations_alongside_keep_one_slot_per_point_until_an_episode_has_ended():
    agent, env = agent_for(CONFIG)
    points = EvalPoints(CONFIG.replace(eval_alongside=True), env)
    assert points.depth == 3 == -(-env.max_episode_steps // CONFIG.iterations_per_eval)
    actor = agent.init(jax.random.key(0)).actor_params
    pending = points.init_pending(jax.random.key(1), actor)
    assert pending.episodes.returns.shape == (3 * 2 * points.episodes,)
    assert not np.asarray(pending.active).any() and not np.asarray(pending.episodes.alive).any()
    assert EvalPoints(CONFIG, env).init_pending(jax.random.key(1), actor) is None
