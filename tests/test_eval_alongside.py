"""`SACConfig.eval_alongside`: evaluations stepped alongside training score the same actors on
the same episodes as evaluations run at their point, D points later (D = ceil(max episode
steps / iterations per evaluation)), or all at the run's last point; the kept actor measured
beside them counts only if it is still kept then (`sac_jax.selection`); training is
unchanged."""

import jax
import numpy as np
import pytest

import sac_jax
from sac_jax.train import make_train
from tests.test_selection import replay_selection

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
    # the same actors on the same initial states; batch widths differ (float rounding)
    np.testing.assert_allclose(alongside["eval_return"][DEPTH:last],
                               at_point["eval_return"][:last - DEPTH], rtol=1e-5)
    both = ~np.isnan(alongside["confirm_return"][DEPTH:last]) & ~np.isnan(
        at_point["confirm_return"][:last - DEPTH])
    assert both.sum() >= 2
    np.testing.assert_allclose(alongside["confirm_return"][DEPTH:last][both],
                               at_point["confirm_return"][:last - DEPTH][both], rtol=1e-5)
    np.testing.assert_array_equal(alongside["env_steps"], at_point["env_steps"])
    # the last point runs every evaluation under way to its end: its own actor's is the last
    np.testing.assert_allclose(alongside["eval_return"][last], at_point["eval_return"][last],
                               rtol=1e-5)


def test_selection_follows_its_rules_with_and_without_the_kept_actors_returns(runs):
    """Up to the last point (which selects on all D evaluations under way at once), the
    delivered return follows the selection's rules on the returns reported D points late; the
    kept actor's return was used where it was still the kept actor and not after a
    replacement had overtaken its measurement."""
    alongside = {name: values[DEPTH:CONFIG.num_evals - 1] for name, values in runs[True][1].items()}
    scores, points, _ = replay_selection(alongside)
    np.testing.assert_array_equal(alongside["delivered_return"], scores)
    used = ~np.isnan(alongside["kept_return"])
    assert used[1:].any() and not used[1:].all()
    # which point's actor is kept after each row (none before the first); the evaluation
    # scored at row j began at row j - D beside the actor kept then, whose return counts iff
    # that actor is still the kept one (not implied by the replay, which reads `used`)
    kept = lambda j: points[j] if j >= 0 else -1
    expected = [kept(j - 1) == kept(j - DEPTH) != -1 for j in range(len(points))]
    np.testing.assert_array_equal(used[1:], expected[1:])


def test_unchanged_training_and_everything_scored(runs):
    (at_point, _), (alongside, outputs) = runs[False], runs[True]
    same = jax.tree_util.tree_map(np.array_equal, alongside.sac.actor_params,
                                  at_point.sac.actor_params)
    assert all(jax.tree_util.tree_leaves(same))
    assert not np.any(np.asarray(alongside.pending.active))  # all scored at the end
    assert int(alongside.delivered.env_steps) in outputs["env_steps"]
    assert float(alongside.delivered.score) == outputs["delivered_return"][-1]
