"""Brax environments by name (envs/brax_tasks.py): the adapter against the Brax environment
stepped directly (same draws, same observations and rewards; Brax's `done` a termination; the
1000-step limit a truncation that keeps the true final observation; actions clipped to the
actuators' bounds; fresh random starts), the one-line error for an unknown name, and a short
CPU run whose delivered policy balances in Brax's environment itself."""

import inspect

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import envs
import sac_jax
from envs import brax_tasks
from sac_jax.run import run_training
from sac_jax.train import agent_for
from tests.task_steps import side_by_side

NAME = "brax/inverted_pendulum"


@pytest.fixture(scope="module")
def env():
    return envs.make(NAME)


def test_the_task_list_is_braxs():
    from brax import envs as brax_envs

    assert set(brax_tasks.TASKS) == set(brax_envs._envs) - {"fast"}
    assert set(envs.registered()) >= {brax_tasks.PREFIX + t for t in brax_tasks.TASKS}
    assert envs.spec(NAME).solved_return is None and envs.spec(NAME).gymnasium_id is None


def test_steps_are_the_tasks_own_and_done_terminates(env):
    """A fixed action sequence through the adapter and through Brax's environment from the
    same key: equal observations and rewards at every step, and the adapter terminates exactly
    where Brax's `done` is first set (the pole falls under these pushes)."""
    task = brax_tasks._load("inverted_pendulum")
    actions = jnp.full((200, 1), 0.5)

    key = jax.random.key(3)
    (obs, reward, terminated, truncated), (task_obs, task_reward, done) = side_by_side(
        env, task, key, actions)
    np.testing.assert_array_equal(env.reset(key).obs, task.reset(key).obs)
    end = int(np.argmax(np.asarray(done) > 0))
    assert 0 < end < 200 and bool(terminated[end]) and not np.any(terminated[:end])
    np.testing.assert_array_equal(obs[:end + 1], task_obs[:end + 1])
    np.testing.assert_array_equal(reward[:end + 1], task_reward[:end + 1])
    assert not np.any(truncated)


def test_the_limit_truncates_with_the_final_observation(env):
    """Near the limit, a step that ends the episode by time truncates (not terminates) and
    returns the task's own next observation."""
    state = env.reset(jax.random.key(0))
    late = state.replace(step_count=jnp.int32(env.max_episode_steps - 1))
    after = jax.jit(env.step)(late, jnp.zeros(1))
    assert env.max_episode_steps == brax_tasks.EPISODE_LENGTH == 1000
    assert bool(after.truncated) and not bool(after.terminated)
    np.testing.assert_array_equal(after.obs, brax_tasks._load("inverted_pendulum").step(
        state.data, jnp.zeros(1)).obs)


def test_actions_span_the_actuators_range_clipped_and_resets_draw_fresh_starts(env):
    """inverted_pendulum's step maps [-1, 1] onto its ctrlrange [-3, 3] itself: our bounds are
    [-1, 1], each action reaches the control it names, and one beyond is clipped to the bound
    (MJX clamps ctrl itself, so equal observations alone would not show it)."""
    model = brax_tasks._load("inverted_pendulum").sys.mj_model
    np.testing.assert_array_equal(model.actuator_ctrlrange, [[-3.0, 3.0]])
    np.testing.assert_array_equal(env.action_low, [-1.0])
    np.testing.assert_array_equal(env.action_high, [1.0])
    state = env.reset(jax.random.key(0))
    ctrl = lambda a: np.asarray(env.step(state, jnp.array([a])).data.pipeline_state.ctrl)
    np.testing.assert_allclose([ctrl(a) for a in (-1.0, -0.5, 0.0, 1.0, 4.0, -4.0)],
                               [[-3.0], [-1.5], [0.0], [3.0], [3.0], [-3.0]], atol=1e-6)
    np.testing.assert_array_equal(env.step(state, jnp.array([4.0])).obs,
                                  env.step(state, jnp.array([1.0])).obs)
    after = env.step(state, jnp.array([jnp.nan]))
    assert bool(after.terminated) and np.all(np.isfinite(after.obs))
    starts = jax.vmap(env.reset)(jax.random.split(jax.random.key(0), 8)).obs
    assert len({tuple(np.asarray(o)) for o in starts}) == 8


def test_unit_actions_lists_the_tasks_whose_step_rescales_the_action():
    """`brax_tasks.UNIT_ACTIONS` is exactly the tasks whose `step` maps [-1, 1] onto the
    actuators' `ctrl_range` (read from Brax's source; the others set the action as `ctrl`,
    all of them within [-1, 1]); pusher's [-2, 2] is offered as [-1, 1]."""
    from brax import envs as brax_envs

    rescaling = {name for name in brax_tasks.TASKS
                 if "ctrl_range" in inspect.getsource(brax_envs._envs[name].step)}
    assert rescaling == set(brax_tasks.UNIT_ACTIONS)
    pusher = envs.make("brax/pusher")
    np.testing.assert_array_equal(brax_tasks._load("pusher").sys.mj_model.actuator_ctrlrange,
                                  [[-2.0, 2.0]] * 7)
    np.testing.assert_array_equal((pusher.action_low, pusher.action_high), [[-1.0] * 7,
                                                                            [1.0] * 7])


def test_an_unknown_brax_name_fails_in_one_line():
    with pytest.raises(ValueError, match=r"^unknown Brax environment 'brax/halfcheeta'; "
                                         r"did you mean brax/halfcheetah"):
        envs.make("brax/halfcheeta")


@pytest.mark.slow
def test_the_fast_preset_delivers_a_policy_that_balances_in_braxs_own_environment():
    """`fast` on brax/inverted_pendulum, 1 seed: the delivered actor, run deterministically in
    Brax's environment itself (no adapter, 5 fresh starts), keeps the pole up (Brax's `done`
    never set) for all 1000 steps of Brax's episode."""
    config = sac_jax.PRESETS["fast"].replace(env=NAME)
    result = run_training(config, seeds=1)
    agent, _ = agent_for(config)
    actor = jax.tree_util.tree_map(lambda x: x[0], result.state.delivered.actor_params)
    task = brax_tasks._load("inverted_pendulum")

    def episode(key):
        def step(state, _):
            state = task.step(state, agent.act(actor, state.obs[None])[0])
            return state, state.done
        return jax.lax.scan(step, task.reset(key), length=brax_tasks.EPISODE_LENGTH)[1]

    done = jax.jit(jax.vmap(episode))(jax.random.split(jax.random.key(2026), 5))
    assert not np.any(done), np.argmax(done, axis=1)
