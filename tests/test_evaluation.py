"""`sac_jax.evaluate`: the returns of episodes run in parallel in lock-step equal those of the
same episodes (same initial states, from `initial_states`) run one at a time to their end."""

import jax
import numpy as np
import pytest

import sac_jax
from sac_jax.evaluation import initial_states
from sac_jax.train import agent_for

EPISODES = 6


@pytest.fixture(scope="module")
def setup():
    agent, env = agent_for(sac_jax.PRESETS["fast"])
    params = agent.init(jax.random.key(0)).actor_params
    return agent, env, params, jax.random.key(1)


def one_at_a_time(agent, env, params, key):
    """Each episode stepped alone from its initial state until it terminates or truncates."""
    step = jax.jit(lambda state, params: env.step(state, agent.act(params, state.obs)))
    starts = initial_states(env, jax.random.split(key, EPISODES))
    returns = []
    for i in range(EPISODES):
        state, total, done = jax.tree_util.tree_map(lambda x: x[i], starts), 0.0, False
        while not done:
            state = step(state, params)
            total += float(state.reward)
            done = bool(state.terminated | state.truncated)
        returns.append(total)
    return np.array(returns, np.float32)


def test_returns_equal_episodes_run_one_at_a_time(setup):
    agent, env, params, key = setup
    returns = np.asarray(jax.jit(sac_jax.evaluate, static_argnums=(0, 1, 4))(
        agent, env, params, key, EPISODES))
    assert returns.shape == (EPISODES,)
    # InvertedPendulum pays 1 per step: the returns are the episode lengths; an untrained policy
    # lets the pendulum fall at different steps, so episodes end while others still run.
    assert len(set(returns.tolist())) > 1
    np.testing.assert_array_equal(returns, one_at_a_time(agent, env, params, key))
