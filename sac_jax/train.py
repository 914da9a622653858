"""`make_train(config) -> train(key)`: a whole SAC run as one pure, jit-able, vmap-able function.

One `lax.scan` runs all iterations; iteration i:
    act       uniform random actions while i < learning_starts / num_envs (prefill), then
              a ~ pi(.|s) on all num_envs environments
    step      `envs.VectorEnv.step` (auto-reset), add the num_envs transitions to the buffer
    learn     after the prefill: updates_per_step `sac_update`s on freshly sampled batches
    evaluate  after every eval_every training steps: deterministic returns on separate
              environment instances, and the period's metric means written to the outputs

The environment step, the update and the evaluation each appear once in the traced program
(prefill and training share the iteration; phases switch with `lax.cond` on the iteration
count, which stays a real branch under `vmap`), which keeps compile time down.
`jax.jit(train)` compiles one program; `jax.jit(jax.vmap(train))(keys)` trains many seeds in it.

The same loop comes in pieces from `make_train_parts`: `init(key)` and `chunk(runner)`, a scan
over `chunk_iterations` iterations (a divisor of both the prefill and the evaluation period, so
every evaluation falls at the end of a chunk). `train` scans `chunk`; a host loop can instead
call a jitted `chunk` repeatedly to report progress between chunks, with no host callback in
the program, so JAX's persistent compilation cache can keep it (`sac_jax.run` does this).
"""

from __future__ import annotations

import math
from typing import Callable, Dict, NamedTuple, Optional, Tuple

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
    """Everything a run carries between iterations. `iteration` counts iterations done;
    `sums` accumulates the current evaluation period's metrics as (sum, count) pairs;
    `outputs` holds one slot per evaluation point."""

    sac: SACState
    env: envs.VectorState
    buffer: ReplayBuffer
    key: jax.Array
    iteration: jax.Array
    sums: Dict[str, jax.Array]
    outputs: Dict[str, jax.Array]


class TrainParts(NamedTuple):
    """`init(key) -> RunnerState`; `chunk(runner) -> runner`, `chunk_iterations` iterations
    (evaluating where an evaluation period ends); `num_chunks` chunks make the run."""

    init: Callable[[jax.Array], RunnerState]
    chunk: Callable[[RunnerState], RunnerState]
    chunk_iterations: int
    num_chunks: int


def agent_for(config: SACConfig) -> Tuple[Agent, object]:
    """The agent sized for `config.env`, and that environment."""
    env = envs.make(config.env)
    return make_agent(config, env.observation_size, env.action_size, env.action_low,
                      env.action_high), env


def make_train_parts(config: SACConfig,
                     progress: Optional[Callable[[Dict[str, jax.Array]], None]] = None
                     ) -> TrainParts:
    """The training loop as `TrainParts` (see the module docstring and `make_train`)."""
    agent, env = agent_for(config)
    vec = envs.VectorEnv(env, config.num_envs)
    low, high = jnp.asarray(agent.action_low), jnp.asarray(agent.action_high)
    n, prefill, period = config.num_envs, config.prefill_iterations, config.iterations_per_eval
    chunk_iterations = math.gcd(prefill, period)
    sum_names = METRIC_NAMES + ("train_return",)
    nan = jnp.float32(jnp.nan)

    def learn(sac: SACState, buffer: ReplayBuffer, key: jax.Array):
        # All minibatches of the iteration are gathered at once, then scanned over.
        k_batch, k_noise = jax.random.split(key)
        batches = rb.sample(buffer, k_batch, (config.updates_per_step, config.batch_size))
        sac, metrics = jax.lax.scan(
            lambda sac, xs: sac_update(agent, sac, *xs), sac,
            (batches, jax.random.split(k_noise, config.updates_per_step)))
        return sac, {name: jnp.nanmean(metrics[name]) if name in metrics else nan
                     for name in METRIC_NAMES}

    def evaluate_period(runner: RunnerState) -> RunnerState:
        index = (runner.iteration - prefill) // period - 1
        key, k_eval = jax.random.split(runner.key)
        out = {name: total / count for name, (total, count) in runner.sums.items()}
        out["eval_return"] = jnp.mean(
            evaluate(agent, env, runner.sac.actor_params, k_eval, config.eval_episodes))
        out["env_steps"] = config.learning_starts + (index + 1) * config.eval_every
        if progress is not None:
            jax.debug.callback(progress, out)
        outputs = {name: runner.outputs[name].at[index].set(out[name]) for name in out}
        sums = jax.tree_util.tree_map(jnp.zeros_like, runner.sums)
        return runner.replace(key=key, sums=sums, outputs=outputs)

    def iteration(runner: RunnerState, _):
        learning = runner.iteration >= prefill
        key, k_act, k_random, k_learn = jax.random.split(runner.key, 4)
        obs = runner.env.env_state.obs
        action = jnp.where(learning, agent.act(runner.sac.actor_params, obs, k_act),
                           jax.random.uniform(k_random, (n, agent.action_size), minval=low,
                                              maxval=high))
        env_state, step = vec.step(runner.env, action)
        buffer = rb.add(runner.buffer, Transition(
            obs=obs, action=action, reward=step.reward, next_obs=step.final_obs,
            terminated=step.terminated.astype(jnp.float32)))
        sac, metrics = jax.lax.cond(
            learning, lambda sac: learn(sac, buffer, k_learn),
            lambda sac: (sac, {name: nan for name in METRIC_NAMES}), runner.sac)
        metrics["train_return"] = jnp.sum(jnp.where(step.done, step.episode_return, 0.0))
        counts = {name: jnp.isfinite(m).astype(jnp.float32) for name, m in metrics.items()}
        counts["train_return"] = jnp.sum(step.done).astype(jnp.float32)
        sums = {name: (total + jnp.where(jnp.isfinite(metrics[name]), metrics[name], 0.0),
                       count + counts[name])
                for name, (total, count) in runner.sums.items()}
        return runner.replace(sac=sac, env=env_state, buffer=buffer, key=key, sums=sums,
                              iteration=runner.iteration + 1), None

    def chunk(runner: RunnerState) -> RunnerState:
        runner, _ = jax.lax.scan(iteration, runner, None, length=chunk_iterations)
        after_prefill = runner.iteration - prefill
        return jax.lax.cond((after_prefill > 0) & (after_prefill % period == 0),
                            evaluate_period, lambda r: r, runner)

    def init(key: jax.Array) -> RunnerState:
        k_sac, k_env, k_run = jax.random.split(key, 3)
        env_state = vec.reset(k_env)
        example = Transition(obs=env_state.env_state.obs[0],
                             action=jnp.zeros(agent.action_size, jnp.float32),
                             reward=jnp.float32(0), next_obs=env_state.env_state.obs[0],
                             terminated=jnp.float32(0))
        zero = jnp.float32(0)
        return RunnerState(
            sac=agent.init(k_sac), env=env_state, buffer=rb.init(config.buffer_size, example),
            key=k_run, iteration=jnp.int32(0), sums={name: (zero, zero) for name in sum_names},
            outputs={"env_steps": jnp.zeros(config.num_evals, jnp.int32),
                     **{name: jnp.full(config.num_evals, jnp.nan, jnp.float32)
                        for name in sum_names + ("eval_return",)}})

    total = prefill + config.num_evals * period
    return TrainParts(init, chunk, chunk_iterations, total // chunk_iterations)


def make_train(config: SACConfig,
               progress: Optional[Callable[[Dict[str, jax.Array]], None]] = None):
    """Returns `train(key) -> (RunnerState, metrics)`, the whole run as one scan.

    metrics: arrays with a leading axis of `config.num_evals` evaluation points:
    `env_steps` (environment steps done), `eval_return` (mean deterministic return over
    `eval_episodes`), `train_return` (mean return of training episodes ended in the period, NaN
    if none), and the period means of the update metrics in `METRIC_NAMES` (NaN where unused).
    `progress`, if given, is called on the host with each evaluation point's metrics (through
    `jax.debug.callback`; under `vmap` once per seed). A program with a host callback is not
    kept by JAX's persistent compilation cache; `sac_jax.run` reports progress between chunks.
    """
    parts = make_train_parts(config, progress)

    def train(key: jax.Array):
        runner = jax.lax.scan(lambda r, _: (parts.chunk(r), None), parts.init(key), None,
                              length=parts.num_chunks)[0]
        return runner, runner.outputs

    return train
