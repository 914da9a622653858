"""`SACConfig.eval_alongside`: evaluations stepped alongside training score the same actors on
the same episodes as evaluations run at their point, D points later (D = ceil(max episode
steps / iterations per evaluation)), or all at the run's last point; training is unchanged."""

import jax
import numpy as np
import pytest

import sac_jax
from sac_jax.train import make_train

# Pendulum-v1 (200-step episodes), 4 environments, 75 iterations per evaluation: D = 3
CONFIG = sac_jax.PRESETS["pendulum"].replace(
    num_envs=4, total_steps=5_200, learning_starts=1_000, eval_every=300, eval_episodes=3,
    confirm_episodes=4, actor_hidden=(32, 32), critic_hidden=(32, 32))
DEPTH = 3


@pytest.fixture(scope="module")
def runs():
    """{eval_alongside: (final runner, outputs)} of one key."""
    out = {}
    for alongside in (False, True):
        runner, metrics = jax.jit(make_train(CONFIG.replace(eval_alongside=alongside)))(
            jax.random.key(3))
        out[alongside] = runner, {k: np.asarray(v) for k, v in metrics.items()}
    return out


def test_depth_covers_an_episode():
    assert DEPTH == -(-200 // CONFIG.iterations_per_eval) and CONFIG.num_evals > 2 * DEPTH


def test_each_evaluation_ends_depth_points_later(runs):
    at_point, alongside = runs[False][1], runs[True][1]
    last = CONFIG.num_evals - 1
    assert np.all(np.isnan(alongside["eval_return"][:DEPTH]))  # none has ended yet
    for name in ("eval_return", "confirm_return", "delivered_return"):
        # the same actors on the same initial states; batch widths differ (float rounding)
        np.testing.assert_allclose(alongside[name][DEPTH:last], at_point[name][:last - DEPTH],
                                   rtol=1e-5, err_msg=name)
    np.testing.assert_array_equal(alongside["env_steps"], at_point["env_steps"])
    # the last point runs every evaluation under way to its end: its own actor's is the last
    np.testing.assert_allclose(alongside["eval_return"][last], at_point["eval_return"][last],
                               rtol=1e-5)


def test_same_delivered_actor_and_unchanged_training(runs):
    (at_point, _), (alongside, _) = runs[False], runs[True]
    np.testing.assert_allclose(alongside.delivered.score, at_point.delivered.score, rtol=1e-5)
    assert int(alongside.delivered.env_steps) == int(at_point.delivered.env_steps)
    same = jax.tree_util.tree_map(np.array_equal, alongside.sac.actor_params,
                                  at_point.sac.actor_params)
    assert all(jax.tree_util.tree_leaves(same))
    assert not np.any(np.asarray(alongside.pending.active))  # all scored at the end
