"""Deterministic evaluation of a policy on its own environment instances, inside jit."""

from __future__ import annotations

from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp

from envs.vector import where_rows
from sac_jax.agent import Agent


def initial_states(env, keys: jax.Array):
    """The batched `EnvState` of a fresh episode per key (leading axis len(keys)); `evaluate(...,
    key, num_episodes)` starts from those of `jax.random.split(key, num_episodes)`."""
    return jax.vmap(env.reset)(keys)


def evaluate(agent: Agent, env, actor_params, key: jax.Array, num_episodes: int) -> jax.Array:
    """Undiscounted returns (num_episodes,) of the mean action scale * tanh(mu(s)) + bias.

    Runs `num_episodes` fresh episodes in parallel until each terminates or truncates (a
    `lax.while_loop` that stops when all have ended); rewards after an episode's end are ignored.

    The batch steps in lock-step, so an ended episode is still stepped until the last one ends:
    from its initial state with a zero action, never on from where it ended nor with its
    policy's action. This kept fallen pendulums out of their joint limits while MJX's iterative
    constraint solver made limit contact costly on a GPU (H100: 2.2 s against 7.2 s stepping
    on, for 256 x 5 episodes half ended early). With `envs.active_set_solver` a step costs the
    same either way (H100, 256 x 5 episodes: 0.61 s against 0.64 s,
    `benchmarks/results/evaluation_cost-h100.json`). `tests/test_evaluation.py` checks the
    returns against episodes run one by one.
    """
    return evaluate_from(agent, env, actor_params,
                         initial_states(env, jax.random.split(key, num_episodes)))


def evaluate_from(agent: Agent, env, actor_params, start) -> jax.Array:
    """`evaluate` from the batched initial `EnvState` `start` (leading axis: episodes); each
    episode's return depends on its own initial state only (up to float rounding), so episodes
    of several evaluations can share one batch.

    The loop also stops after `env.max_episode_steps` steps, where every episode has been
    truncated anyway. The bound is there for XLA: a loop condition that reads a single carried
    value makes XLA's while-loop passes try to find its trip count by extracting all that the
    body computes for that value, here the whole environment step, on every pass. With two,
    they give up at once: `fast`'s evaluation program compiles in 2.9-3.7 s instead of
    4.0-4.9 s (4.1-5.0 CPU-s instead of 5.1-6.0) on 2 CPU cores, with the same results.
    """
    return run_episodes(env, lambda obs: agent.act(actor_params, obs), begin(start)).returns


def run_episodes(env, act: Callable[[jax.Array], jax.Array], episodes: "Episodes") -> "Episodes":
    """Steps `episodes` with `act` (`step_episodes`) until all have ended or `episodes.steps`
    reaches `env.max_episode_steps` (see `evaluate_from`)."""
    def running(episodes: Episodes):
        return jnp.any(episodes.alive) & (episodes.steps < env.max_episode_steps)

    return jax.lax.while_loop(running, lambda e: step_episodes(env, act, e), episodes)


class Episodes(NamedTuple):
    """A batch of evaluation episodes under way (leading axis: episodes): `start` their
    initial states, `states` the current ones, `alive` (E,) bool whether each is still running,
    `returns` (E,) float32 the rewards summed so far, `steps` () int32 steps taken."""

    start: Any
    states: Any
    alive: jax.Array
    returns: jax.Array
    steps: jax.Array


def begin(start) -> Episodes:
    """The episodes from the batched initial `EnvState` `start`, before their first step."""
    num_episodes = start.obs.shape[0]
    return Episodes(start, start, jnp.ones(num_episodes, bool),
                    jnp.zeros(num_episodes, jnp.float32), jnp.int32(0))


def step_episodes(env, act: Callable[[jax.Array], jax.Array], episodes: Episodes) -> Episodes:
    """One step of every episode with the deterministic actions `act(obs)` (E, action size); an
    ended episode steps from its initial state with a zero action, and its return no longer
    changes (see `evaluate`)."""
    start, states, alive, returns, steps = episodes
    states = where_rows(alive, states, start)
    action = jnp.where(alive[:, None], act(states.obs), 0.0)
    states = jax.vmap(env.step)(states, action)
    returns = returns + jnp.where(alive, states.reward, 0.0)
    alive = alive & ~(states.terminated | states.truncated)
    return Episodes(start, states, alive, returns, steps + 1)
