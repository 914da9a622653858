"""`make_train(config) -> train(key)`: a whole SAC run as one pure, jit-able, vmap-able function.

    prefill:  learning_starts / num_envs iterations of uniform random actions into the buffer
    train:    num_evals x [ iterations_per_eval x iteration ; deterministic evaluation ]
    iteration: act on all num_envs environments, step them (auto-reset), add the num_envs
               transitions to the buffer, run updates_per_step `sac_update`s on sampled batches

Everything is `lax.scan`/`lax.while_loop`, so `jax.jit(train)` compiles one program and
`jax.jit(jax.vmap(train))(keys)` trains many seeds in it.
"""

from __future__ import annotations

from typing import Callable, Dict, Optional, Tuple

import flax.struct
import jax
import jax.numpy as jnp

import envs
from sac_jax import replay_buffer as rb
from sac_jax.agent import Agent, SACState, make_agent
from sac_jax.config import SACConfig
from sac_jax.evaluation import evaluate
from sac_jax.replay_buffer import ReplayBuffer, Transition
from sac_jax.updates import sac_update

METRIC_NAMES = ("critic_loss", "q", "actor_loss", "entropy", "alpha_loss", "alpha", "value_loss")


class RunnerState(flax.struct.PyTreeNode):
    """Everything a run carries between iterations."""

    sac: SACState
    env: envs.VectorState
    buffer: ReplayBuffer
    key: jax.Array


def agent_for(config: SACConfig) -> Tuple[Agent, object]:
    """The agent sized for `config.env`, and that environment."""
    env = envs.make(config.env)
    return make_agent(config, env.observation_size, env.action_size, env.action_low,
                      env.action_high), env


def make_train(config: SACConfig,
               progress: Optional[Callable[[Dict[str, jax.Array]], None]] = None):
    """Returns `train(key) -> (RunnerState, metrics)`.

    metrics: arrays with a leading axis of `config.num_evals` evaluation points:
    `env_steps` (environment steps done), `eval_return` (mean deterministic return over
    `eval_episodes`), `train_return` (mean return of training episodes ended in the period, NaN
    if none), and the period means of the update metrics in `METRIC_NAMES` (NaN where unused).
    `progress`, if given, is called on the host with that evaluation point's metrics (through
    `jax.debug.callback`; under `vmap` once per seed).
    """
    agent, env = agent_for(config)
    vec = envs.VectorEnv(env, config.num_envs)
    low, high = jnp.asarray(agent.action_low), jnp.asarray(agent.action_high)
    n = config.num_envs

    def add(buffer, obs, action, step):
        return rb.add(buffer, Transition(obs=obs, action=action, reward=step.reward,
                                         next_obs=step.final_obs,
                                         terminated=step.terminated.astype(jnp.float32)))

    def prefill_iteration(runner: RunnerState, _):
        key, k_act = jax.random.split(runner.key)
        obs = runner.env.env_state.obs
        action = jax.random.uniform(k_act, (n, agent.action_size), minval=low, maxval=high)
        env_state, step = vec.step(runner.env, action)
        return runner.replace(env=env_state, buffer=add(runner.buffer, obs, action, step),
                              key=key), None


    def iteration(runner: RunnerState, _):
        key, k_act, k_update = jax.random.split(runner.key, 3)
        obs = runner.env.env_state.obs
        action = agent.act(runner.sac.actor_params, obs, k_act)
        env_state, step = vec.step(runner.env, action)
        buffer = add(runner.buffer, obs, action, step)
        # All minibatches of the iteration are gathered at once, outside the update loop, so the
        # loop never holds the buffer (XLA would copy it on every iteration).
        k_batch, k_noise = jax.random.split(k_update)
        batches = rb.sample(buffer, k_batch, (config.updates_per_step, config.batch_size))
        sac, metrics = jax.lax.scan(
            lambda sac, xs: sac_update(agent, sac, *xs), runner.sac,
            (batches, jax.random.split(k_noise, config.updates_per_step)))
        episodes = (jnp.sum(jnp.where(step.done, step.episode_return, 0.0)),
                    jnp.sum(step.done))
        return (runner.replace(sac=sac, env=env_state, buffer=buffer, key=key),
                (metrics, episodes))

    def period(runner: RunnerState, index):
        runner, (metrics, (return_sum, episode_count)) = jax.lax.scan(
            iteration, runner, None, length=config.iterations_per_eval)
        key, k_eval = jax.random.split(runner.key)
        out = {name: jnp.nanmean(metrics[name]) if name in metrics else jnp.float32(jnp.nan)
               for name in METRIC_NAMES}
        count = jnp.sum(episode_count)
        out["train_return"] = jnp.where(count > 0, jnp.sum(return_sum) / jnp.maximum(count, 1),
                                        jnp.nan)
        out["eval_return"] = jnp.mean(
            evaluate(agent, env, runner.sac.actor_params, k_eval, config.eval_episodes))
        out["env_steps"] = config.learning_starts + (index + 1) * config.eval_every
        if progress is not None:
            jax.debug.callback(progress, out)
        return runner.replace(key=key), out

    def train(key: jax.Array):
        k_sac, k_env, k_run = jax.random.split(key, 3)
        env_state = vec.reset(k_env)
        example = Transition(obs=env_state.env_state.obs[0],
                             action=jnp.zeros(agent.action_size, jnp.float32),
                             reward=jnp.float32(0), next_obs=env_state.env_state.obs[0],
                             terminated=jnp.float32(0))
        runner = RunnerState(sac=agent.init(k_sac), env=env_state,
                             buffer=rb.init(config.buffer_size, example), key=k_run)
        runner, _ = jax.lax.scan(prefill_iteration, runner, None,
                                 length=config.prefill_iterations)
        return jax.lax.scan(period, runner, jnp.arange(config.num_evals))

    return train
