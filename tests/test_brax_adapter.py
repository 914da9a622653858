"""envs.to_brax: our InvertedPendulum-v5 as a Brax environment, alone and under Brax's training
wrappers, reproduces our environment's own steps.

Four lanes run open-loop Brax actions (in [-1, 1]) for T steps with a time limit of 8 steps:
action 0 keeps the pole up past the limit (truncation), +-1 push it over within the limit
(termination at the bounds +-3), and 2 lies outside [-1, 1] (mapped to 6, clipped to 3).
"""

from __future__ import annotations

import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import envs

LIMIT, T = 8, 40
BRAX_ACTIONS = jnp.array([0.0, 1.0, -1.0, 2.0])[None, :, None] * jnp.ones((T, 1, 1))
KEYS = jax.random.split(jax.random.PRNGKey(0), BRAX_ACTIONS.shape[1])


@pytest.fixture(scope="module")
def env():
    return envs.make("InvertedPendulum-v5", max_episode_steps=LIMIT)


def ours_action(env, a):
    """Brax's [-1, 1] action mapped onto our bounds: low + (a + 1)(high - low) / 2."""
    return env.action_low + (a + 1.0) * (env.action_high - env.action_low) / 2


@pytest.fixture(scope="module")
def reference(env):
    """Our env stepped directly; on terminated or truncated it restarts from its first state,
    as Brax's AutoResetWrapper does. Returns numpy arrays of shape (T, lanes, ...)."""

    def lane(key, actions):
        first = env.reset(key)

        def step(s, a):
            s = env.step(s, ours_action(env, a))
            done = s.terminated | s.truncated
            out = dict(obs=jnp.where(done, first.obs, s.obs), reward=s.reward,
                       terminated=s.terminated, done=done,
                       truncation=s.truncated & ~s.terminated)
            return jax.tree.map(lambda x0, x: jnp.where(done, x0, x), first, s), out

        return jax.lax.scan(step, first, actions)[1]

    out = jax.jit(jax.vmap(lane, in_axes=(0, 1), out_axes=1))(KEYS, BRAX_ACTIONS)
    return jax.tree.map(np.asarray, out)


def brax_rollout(benv, actions):
    """`benv` (batched by a Brax wrapper) reset with KEYS and stepped under `actions`
    (T, lanes, 1); returns numpy obs, reward, done and info['truncation'] (zeros if absent)."""

    def rollout(actions):
        def step(state, a):
            state = benv.step(state, a)
            truncation = state.info.get("truncation", jnp.zeros_like(state.done))
            return state, dict(obs=state.obs, reward=state.reward, done=state.done,
                               truncation=truncation)

        return jax.lax.scan(step, benv.reset(KEYS), actions)[1]

    return jax.tree.map(np.asarray, jax.jit(rollout)(actions))


def test_reference_covers_both_endings(reference):
    """The lanes exercise what the comparison is about: truncations and terminations."""
    assert reference["truncation"][:, 0].sum() >= 3 and not reference["terminated"][:, 0].any()
    for lane in (1, 2, 3):
        assert reference["terminated"][:, lane].sum() >= 3
        assert not reference["truncation"][:, lane].any()


def test_properties(env):
    from brax.envs.base import Env as BraxEnv

    benv = envs.to_brax(env)
    assert isinstance(benv, BraxEnv) and benv.env is env and benv.unwrapped is benv
    assert (benv.observation_size, benv.action_size, benv.max_episode_steps) == (4, 1, LIMIT)
    assert isinstance(benv.backend, str)


def test_actions_in_minus_one_one_map_onto_asymmetric_bounds():
    """a_env = low + (a + 1)(high - low) / 2: -1 to low, 1 to high, 0 to the midpoint (the
    lanes below have symmetric bounds, where the offset `low` would not show)."""
    ours = envs.make("InvertedPendulum-v5")
    benv = envs.to_brax(ours)
    state = benv.reset(jax.random.key(0))
    benv._low, benv._half_range = jnp.array([-1.0]), jnp.array([2.0])  # bounds (-1, 3)
    given = []

    class Recorder:  # our env, recording the action each step is given
        def step(self, s, a):
            given.append(np.asarray(a))
            return ours.step(s, a)

    benv._env = Recorder()
    for a in (-1.0, 0.0, 1.0):
        benv.step(state, jnp.array([a]))
    np.testing.assert_allclose(np.concatenate(given), [-1.0, 1.0, 3.0])


def test_adapter_alone_matches_our_env(env):
    """Unwrapped (only vmapped): never reset, done = terminated, obs and reward are ours. The
    same float32 operations in another program: rewards and flags bit for bit; observations to
    1e-6, one float32 ulp of values up to 8 (9.5e-7) where a fusion rounds differently."""
    from brax.envs.wrappers.training import VmapWrapper

    def lane(key, actions):
        def step(s, a):
            s = env.step(s, ours_action(env, a))
            return s, dict(obs=s.obs, reward=s.reward, done=s.terminated.astype(jnp.float32))

        return jax.lax.scan(step, env.reset(key), actions)[1]

    ours = jax.tree.map(np.asarray, jax.jit(jax.vmap(lane, in_axes=(0, 1), out_axes=1))(
        KEYS, BRAX_ACTIONS))
    got = brax_rollout(VmapWrapper(envs.to_brax(env)), BRAX_ACTIONS)
    assert got["done"].dtype == np.float32 and ours["done"].sum() >= 10
    np.testing.assert_allclose(got["obs"], ours["obs"], rtol=0, atol=1e-6)
    np.testing.assert_array_equal(got["reward"], ours["reward"])
    np.testing.assert_array_equal(got["done"], ours["done"])
    assert not got["truncation"].any()


def test_brax_training_wrappers_match_gymnasium_rules(env, reference):
    """Under brax.envs.training.wrap (Vmap, Episode, AutoReset) with episode_length = our time
    limit: done = terminated or truncated, info['truncation'] = truncated and not terminated,
    and the observation after an episode's end is the lane's first one. Observations to 1e-6:
    one float32 ulp of values up to 8 (9.5e-7); rewards and flags bit for bit."""
    from brax.envs import training

    benv = envs.to_brax(env)
    got = brax_rollout(training.wrap(benv, episode_length=benv.max_episode_steps),
                       BRAX_ACTIONS)
    np.testing.assert_allclose(got["obs"], reference["obs"], rtol=0, atol=1e-6)
    np.testing.assert_array_equal(got["reward"], reference["reward"])
    np.testing.assert_array_equal(got["done"], reference["done"].astype(np.float32))
    np.testing.assert_array_equal(got["truncation"], reference["truncation"].astype(np.float32))


@pytest.mark.parametrize("bad", ["InvertedPendulum-v5", None, envs.VectorEnv])
def test_not_an_env_is_refused(bad):
    with pytest.raises(TypeError, match=f"envs.to_brax expects an envs.Env.*{type(bad).__name__}"):
        envs.to_brax(bad)


def test_bad_action_shape_is_refused(env):
    benv = envs.to_brax(env)
    state = benv.reset(KEYS[0])
    with pytest.raises(ValueError, match=r"action shape \(2,\) != \(1,\)"):
        benv.step(state, jnp.zeros(2))


def test_import_envs_does_not_import_brax():
    code = ("import sys, envs; assert 'brax' not in sys.modules; envs.to_brax; "
            "assert 'brax' in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)
