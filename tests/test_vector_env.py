"""VectorEnv: 1024 MJX InvertedPendulum-v5 instances under one jitted reset + ``lax.scan``.

Lane i pushes with a constant action a_i ∈ [-4.5, 4.5] (out-of-bound values included), so
the lanes terminate after different numbers of steps and several times within the run.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import envs

N, T = 1024, 60


@pytest.fixture(scope="module")
def vec():
    return envs.VectorEnv(envs.make("InvertedPendulum-v5"), N)


@pytest.fixture(scope="module")
def run(vec):
    @jax.jit
    def rollout(key, actions):
        v0 = vec.reset(key)
        _, steps = jax.lax.scan(vec.step, v0, actions)
        return v0.replace(key=jax.random.key_data(v0.key)), steps

    actions = jnp.broadcast_to(jnp.linspace(-4.5, 4.5, N)[:, None], (T, N, 1))
    first = jax.tree_util.tree_map(np.asarray, rollout(jax.random.key(0), actions))
    second_v0, _ = rollout(jax.random.key(1), actions)
    return first, np.asarray(second_v0.env_state.obs)


def test_properties(vec):
    assert vec.num_envs == N and vec.env.name == "InvertedPendulum-v5"


def test_reset_distribution(run):
    (v0, _), other_obs = run
    obs = v0.env_state.obs
    assert obs.shape == (N, 4) and obs.dtype == np.float32
    assert np.abs(obs).max() <= 0.01
    assert np.abs(obs.mean(axis=0)).max() < 1.5e-3  # σ of the mean is 1.8e-4
    assert np.unique(obs, axis=0).shape[0] == N
    assert not np.array_equal(obs, other_obs)
    assert (v0.episode_return == 0).all() and (v0.episode_length == 0).all()


def test_step_outputs(run):
    (_, s), _ = run
    assert s.obs.shape == s.final_obs.shape == (T, N, 4)
    assert s.reward.shape == s.done.shape == s.episode_length.shape == (T, N)
    assert s.episode_length.dtype == np.int32 and s.done.dtype == bool
    np.testing.assert_array_equal(s.done, s.terminated | s.truncated)
    assert not s.truncated.any()
    episodes_ended = s.done.sum(axis=0)
    assert episodes_ended.min() > 0 and episodes_ended.max() >= 3
    assert not s.done.all(axis=0).any()


def test_auto_reset_and_final_obs(run):
    (v0, s), _ = run
    done = s.done
    np.testing.assert_array_equal(s.obs[~done], s.final_obs[~done])
    # final_obs is the true terminal observation (|θ| > 0.2), continuous with the previous obs
    assert (np.abs(s.final_obs[done][:, 1]) > 0.2).all()
    previous = np.concatenate([v0.env_state.obs[None], s.obs[:-1]])
    assert np.abs(s.final_obs[..., :2] - previous[..., :2]).max() < 0.3
    # where done, obs is a fresh random reset: in range and never a repeated (cached) state
    fresh = s.obs[done]
    assert np.abs(fresh).max() <= 0.01
    all_resets = np.concatenate([v0.env_state.obs, fresh])
    assert np.unique(all_resets, axis=0).shape[0] == all_resets.shape[0]


def test_episode_statistics(run):
    (_, s), _ = run
    ret, length = np.zeros(N, np.float32), np.zeros(N, np.int32)
    for t in range(T):
        ret, length = ret + s.reward[t], length + 1
        d = s.done[t]
        # rewards of 0 and 1: float32 sums of them are exact (below 2^24), so bit for bit
        np.testing.assert_array_equal(s.episode_return[t][d], ret[d])
        np.testing.assert_array_equal(s.episode_length[t][d], length[d])
        # InvertedPendulum-v5 pays 1 per step and 0 on the terminating step
        np.testing.assert_array_equal(s.episode_return[t][d], length[d] - 1)
        ret[d], length[d] = 0, 0





def test_under_vmap_a_reset_axis_keeps_fresh_states_to_the_steps_where_an_episode_ended():
    """2 seeds of 4 InvertedPendulum-v5 copies vmapped (axis "seeds"), each seed pushing with
    its own constant actions, so their episodes end at different steps. Without `reset_axis`
    the reset `cond`'s predicate differs along the axis, and `vmap` turns it into computing
    fresh states at every step and selecting; with it the program keeps the `cond`. The
    states and steps are the same either way."""
    actions = jnp.stack([jnp.full((40, 4, 1), 3.0), jnp.full((40, 4, 1), -0.5)])
    keys = jax.random.split(jax.random.key(0), 2)

    def rollout(reset_axis):
        vec = envs.VectorEnv(envs.make("InvertedPendulum-v5"), 4, reset_axis=reset_axis)
        seed = lambda key, acts: jax.lax.scan(vec.step, vec.reset(key), acts)
        run = jax.vmap(seed, axis_name="seeds")
        return jax.jit(run)(keys, actions), str(jax.make_jaxpr(run)(keys, actions))

    (final, steps), program = rollout("seeds")
    (final_each, steps_each), program_each = rollout(None)
    ends = np.asarray(steps.done).any(axis=2)  # (seeds, steps): where each seed's episodes end
    assert ends.any(axis=1).all() and (ends[0] != ends[1]).any()
    assert " cond[" in program and " cond[" not in program_each
    same = jax.tree_util.tree_map(lambda a, b: np.array_equal(a, b),
                                  (final.env_state, steps), (final_each.env_state, steps_each))
    assert all(jax.tree_util.tree_leaves(same))
