"""`make_train(config) -> train(key)`: a whole SAC run as one pure, jit-able, vmap-able function.

One `lax.scan` runs all iterations; iteration i:
    act       uniform random actions while i < learning_starts / num_envs (prefill), then
              a ~ pi(.|s) on all num_envs environments
    step      `envs.VectorEnv.step` (auto-reset), add the num_envs transitions to the buffer;
              with `normalize_observations`, add the observations acted on to the running
              statistics (`sac_jax.observation_norm`)
    learn     after the prefill: updates_per_step `sac_update`s on freshly sampled batches
    evaluate  after every eval_every training steps (`sac_jax.eval_point`): deterministic
              returns on separate environment instances, the selection of the delivered actor
              (`sac_jax.selection`: a candidate must beat the kept actor on the same episodes),
              and the period's metric means written to the outputs; with `eval_alongside`,
              the point's episodes are instead stepped once per iteration beside those of the
              D points before it (`Pending`), and scored with the selection D points later,
              D = ceil(episode steps / iterations per point)
    stop      with `stop_when_solved`, a seed whose delivered actor is solved (its kept score,
              averaged over at least `stop_measurements` measurements, at `stop_at`) learns
              no more: its learner state and delivered actor stay as they are

The environment step, the update and the evaluation each appear once in the traced program
(prefill and training share the iteration; phases switch with `lax.cond` on the iteration
count, which stays a real branch under `vmap`), which keeps compile time down.
`jax.jit(train)` compiles one program; `jax.jit(jax.vmap(train))(keys)` trains many seeds in it.
The parts carry `jax.named_scope`s (act, env_step, replay_add, replay_sample, sac_update,
evaluate), by which a profile can sum its kernels (benchmarks/profile_chunk.py).

The same loop comes in pieces from `make_train_parts`: `init(key)`, `advance(runner)`, which
runs the iterations up to the next boundary (the end of the prefill, or the next evaluation
point), and `evaluate(runner)`, which evaluates the point reached; a chunk is `advance` then
`evaluate`, and a run is `num_chunks` chunks. `train` scans chunks; a host loop can instead
call jitted parts repeatedly to report progress between chunks, with no
host callback in the program, so JAX's persistent compilation cache can keep it (`sac_jax.run`
does this). The chunk's loop is a `lax.while_loop` up to that boundary, not a fixed-length
scan: fixed chunks would have to divide both the prefill and the period (for rejax's Pendulum
settings, 256 and 500 iterations: chunks of 4, dispatched 2,500 times, and the host loop cost
1.58x the program's run time on 2 CPU cores). Each trip of that loop runs a block of B
iterations in a fixed-length inner loop, B = gcd(prefill, period): a GPU reads a dynamic
loop's predicate back on the host before every trip (15 us a trip against 5 us in a
fixed-length loop, an H100), and the inner loop's fixed count spares that for B - 1 of every
B iterations (rejax's configuration, B = 4: 1.61-1.62 s against 1.67-1.70 s with one seed, an
H100; the CPU as fast either way).

Randomness: every random draw of acting and learning comes through a source
(`sac_jax.randomness`): a run draws from its PRNG keys (`FromKeys`); `make_train(config,
randomness=replay(config, draws))` replays a recorded stream instead (`record_draws(config,
key)` records the one `train(key)` makes), so a reference implementation fed the same stream
must reproduce the run (tests/test_equivalence_loop.py). Evaluation and environment resets
keep their keys (split from the same chain either way).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable, Dict, NamedTuple, Optional, Tuple

import flax.struct
import jax
import jax.numpy as jnp
import numpy as np

import envs
from sac_jax import replay_buffer as rb
from sac_jax import observation_norm, selection
from sac_jax.agent import Agent, SACState, make_agent
from sac_jax.randomness import Draws, FromKeys, Replay, check
from sac_jax.config import SACConfig
from sac_jax.eval_point import EvalPoints, Pending
from sac_jax.replay_buffer import ReplayBuffer, Transition
from sac_jax.updates import sac_update

METRIC_NAMES = ("critic_loss", "q", "actor_loss", "entropy", "alpha_loss", "alpha", "value_loss")
EVAL_NAMES = ("eval_return", "confirm_return", "kept_return", "delivered_return", "stopped")
"""Per evaluation point: the current actor's mean return over `eval_episodes`; its confirmed
return over `confirm_episodes` fresh episodes (NaN where it was no candidate); the kept actor's
return on those episodes (NaN where not used); the kept score of the delivered actor after the
point (`sac_jax.selection`); 1.0 if the seed has stopped learning after the point
(`stop_when_solved`), else 0.0."""


class RunnerState(flax.struct.PyTreeNode):
    """Everything a run carries between iterations. `iteration` counts iterations done;
    `sums` accumulates the current evaluation period's metrics as (sum, count) pairs;
    `outputs` holds one slot per evaluation point; `delivered` is the kept actor
    (`sac_jax.selection`); `stopped` () bool, whether this seed has stopped learning
    (`SACConfig.stop_when_solved`); `non_finite` () int32, 0 while the learner state is
    finite, else 1 + the index in `non_finite_fields(config)` of the first of its fields that
    held a NaN or an infinity after an update (checked after every update, so the quantity
    that diverged first is named, not one it spread to); `hyperparams` {name: scalar}, the
    hyperparameters this run trains with in place of the config's (`sac_jax.hyperparams`), or
    None; `pending` the evaluations under way (`Pending`) with `SACConfig.eval_alongside`, else
    None."""

    sac: SACState
    env: envs.VectorState
    buffer: ReplayBuffer
    key: jax.Array
    iteration: jax.Array
    sums: Dict[str, jax.Array]
    outputs: Dict[str, jax.Array]
    delivered: selection.Delivered
    stopped: jax.Array
    non_finite: jax.Array
    hyperparams: Optional[Dict[str, jax.Array]] = None
    pending: Optional[Pending] = None


class TrainParts(NamedTuple):
    """`init(key, hyperparams=None) -> RunnerState`; `advance(runner, max_iterations=None) ->
    runner`, the iterations up to the next boundary (the prefill's end, or the next evaluation
    point), at most `max_iterations` (static, the same in every call of a run) if given;
    `evaluate(runner) -> runner`, the evaluation point the runner has reached (nothing
    elsewhere), which reads neither `env` nor `buffer` (they may be None); `chunk` is `advance`
    then `evaluate`, and `num_chunks` chunks make the run's `num_iterations` iterations;
    `record_draws(key) -> Draws`, the stream of the run from `init(key)` drawn from keys (see
    `record_draws`; None for the data-parallel parts of `sac_jax.parallel`)."""

    init: Callable[..., RunnerState]
    advance: Callable[..., RunnerState]
    evaluate: Callable[[RunnerState], RunnerState]
    num_iterations: int
    num_chunks: int
    record_draws: Optional[Callable[[jax.Array], Draws]] = None

    def chunk(self, runner: RunnerState, max_iterations: Optional[int] = None) -> RunnerState:
        return self.evaluate(self.advance(runner, max_iterations))


def _shared_counter_axes() -> RunnerState:
    every = lambda cls: cls(**{f.name: 0 for f in dataclasses.fields(cls)})
    return every(RunnerState).replace(
        sac=every(SACState).replace(step=None), iteration=None,
        buffer=every(ReplayBuffer).replace(position=None, size=None))


SEED_AXES = _shared_counter_axes()
"""`jax.vmap` axes of the `RunnerState` of many seeds trained in lock-step: a leading seed axis
on every array but the counters all seeds share: the iteration count, the update count
`SACState.step` and the replay buffers' write position and size. They stay scalars, so the
predicates of the loop's `lax.cond`s (prefill or learning, evaluation, policy delay, target
period) stay unbatched (under `vmap` a batched predicate turns a `cond` into computing both
branches and selecting), and every seed's buffer is written in place at one position (a
per-seed position turns the write into a scatter)."""


def non_finite_fields(config: SACConfig) -> Tuple[str, ...]:
    """The `SACState` fields `config` trains, in the order an update writes them: each block of
    `config.update_order` (critic: its parameters and optimiser state; value: likewise; actor:
    its parameters and optimiser state, then the temperature's), then the Polyak targets."""
    blocks = {"critic": ("critic_params", "critic_opt_state"),
              "value": ("value_params", "value_opt_state"),
              "actor": ("actor_params", "actor_opt_state", "log_alpha", "alpha",
                        "alpha_opt_state")}
    targets = ("critic_target_params",) if config.variant == "v2" else ("value_target_params",)
    return tuple(f for name in config.update_order for f in blocks[name]) + targets


def _non_finite_code(sac: SACState, fields: Tuple[str, ...]) -> jax.Array:
    """1 + the index in `fields` of the first field of `sac` holding a NaN or an infinity; 0
    if none does. One reduction per field, over its floating leaves concatenated (every update
    of the chunk's scan checks its result): `fast`'s training program compiles in 7.3 CPU-s
    against 7.8 with one reduction per leaf (median of 7 alternated runs, 2 CPU cores)."""
    code = jnp.int32(0)
    for i, name in reversed(list(enumerate(fields))):
        leaves = jax.tree_util.tree_leaves(getattr(sac, name))
        flat = jnp.concatenate([jnp.ravel(x) for x in leaves
                                if jnp.issubdtype(x.dtype, jnp.inexact)] or [jnp.zeros(0)])
        code = jnp.where(jnp.all(jnp.isfinite(flat)), code, jnp.int32(i + 1))
    return code


def _unless_stopped(stopped: jax.Array, old, new):
    """`new`, or `old` where the seed has `stopped` (leaf by leaf; `stop_when_solved`)."""
    return jax.tree_util.tree_map(lambda o, n: jnp.where(stopped, o, n), old, new)


def _learn(agent: Agent, source, watched: Tuple[str, ...], sac: SACState,
           buffer: ReplayBuffer, key: jax.Array, iteration: jax.Array):
    """One iteration's `updates_per_step` `sac_update`s, scanned over minibatches all gathered
    at once. `source` draws the batch indices and each update's noise dict
    (`sac_jax.randomness`). Returns (sac, code, metrics): `code` is the `_non_finite_code` of
    the first update whose result held a NaN or an infinity (0 if none); `metrics`
    {name: mean over the updates} for `METRIC_NAMES`, float32 whatever the parameters' dtype
    (float64 in the x64 equivalence test), NaN for a metric the variant lacks."""
    index, randomness = source.learning(key, buffer.size, iteration)
    with jax.named_scope("replay_sample"):
        batches = rb.gather(buffer, index)

    def update(carry, xs):
        sac, code = carry
        sac, metrics = sac_update(agent, sac, *xs)
        # a few reductions per update: ~0.1% of it on 2 CPU cores; on an H100 the two largest
        # took 6.6 % of PendulumSwingup's update kernel time with 1 seed, 5.5 % with 16
        # (`profile_chunk-PendulumSwingup-h100.json`, its `reduce_and` fusions)
        code = jnp.where(code == 0, _non_finite_code(sac, watched), code)
        return (sac, code), metrics

    with jax.named_scope("sac_update"):
        (sac, code), metrics = jax.lax.scan(update, (sac, jnp.int32(0)), (batches, randomness))
    return sac, code, {name: jnp.nanmean(metrics[name]).astype(jnp.float32) if name in metrics
                       else jnp.float32(jnp.nan) for name in METRIC_NAMES}


def _accumulate(sums: Dict[str, Tuple[jax.Array, jax.Array]], metrics: Dict[str, jax.Array],
                counts: Dict[str, jax.Array]):
    """The period's (sum, count) pairs with this iteration's finite `metrics` added, each
    counting as `counts[name]`."""
    return {name: (total + jnp.where(jnp.isfinite(metrics[name]), metrics[name], 0.0),
                   count + counts[name]) for name, (total, count) in sums.items()}


def agent_for(config: SACConfig) -> Tuple[Agent, object]:
    """The agent sized for `config.env`, and that environment."""
    env = config.make_env()
    return make_agent(config, env.observation_size, env.action_size, env.action_low,
                      env.action_high), env


def make_train_parts(config: SACConfig,
                     progress: Optional[Callable[[Dict[str, jax.Array]], None]] = None,
                     randomness=None, seed_axis: Optional[str] = None) -> TrainParts:
    """The training loop as `TrainParts` (see the module docstring and `make_train`); its
    evaluation points are `sac_jax.eval_point`'s."""
    agent, env = agent_for(config)
    vec = envs.VectorEnv(env, config.num_envs, reset_axis=seed_axis)
    points = EvalPoints(config, env)
    keys = FromKeys(agent, config.num_envs, config.updates_per_step, config.batch_size)
    source = keys if randomness is None else randomness
    n, prefill, period = config.num_envs, config.prefill_iterations, config.iterations_per_eval
    sum_names = METRIC_NAMES + ("train_return",)
    watched = non_finite_fields(config)
    nan = np.float32(np.nan)  # a constant: jnp's would be a computation, compiled at startup

    # The key chain, which `record_draws` follows through the same three splits: init splits
    # (k_sac, k_env, k_run); each iteration splits the run key into (key, k_act, k_learn);
    # each evaluation splits (key, k_eval, k_confirm).
    init_keys = lambda key: jax.random.split(key, 3)
    iteration_keys = lambda key: jax.random.split(key, 3)
    point_keys = lambda key: jax.random.split(key, 3)

    def evaluates_after(iterations_done: jax.Array) -> jax.Array:
        after_prefill = iterations_done - prefill
        return (after_prefill > 0) & (after_prefill % period == 0)

    # Every function below takes the run's agent: `agent` itself, or with the runner's traced
    # hyperparameters (`Agent.with_hyperparams`).
    def evaluate_period(agent: Agent, runner: RunnerState) -> RunnerState:
        index = (runner.iteration - prefill) // period - 1
        key, k_eval, k_confirm = point_keys(runner.key)
        out = {name: total / count for name, (total, count) in runner.sums.items()}
        out["env_steps"] = config.learning_starts + (index + 1) * config.eval_every
        with jax.named_scope("evaluate"):
            delivered, returns, pending = points.evaluate(
                agent, runner.sac.actor_params, runner.delivered, runner.pending, k_eval,
                k_confirm, index, out["env_steps"])
            out["eval_return"], out["confirm_return"], out["kept_return"] = returns
        stopped = runner.stopped
        if config.stop_when_solved:
            delivered = _unless_stopped(stopped, runner.delivered, delivered)
            stopped = stopped | ((delivered.score >= config.stop_at)
                                 & (delivered.count >= config.stop_measurements))
        out["delivered_return"], out["stopped"] = delivered.score, stopped.astype(jnp.float32)
        if progress is not None:
            jax.debug.callback(progress, out)
        outputs = {name: runner.outputs[name].at[index].set(out[name]) for name in out}
        sums = jax.tree_util.tree_map(jnp.zeros_like, runner.sums)
        return runner.replace(key=key, sums=sums, outputs=outputs, delivered=delivered,
                              stopped=stopped, pending=pending)

    def iteration(agent: Agent, runner: RunnerState) -> RunnerState:
        learning = runner.iteration >= prefill
        key, k_act, k_learn = iteration_keys(runner.key)
        random_action, action_noise = source.acting(k_act, runner.iteration)
        obs = runner.env.env_state.obs
        with jax.named_scope("act"):
            action = jnp.where(
                learning, agent.sample_action(runner.sac.actor_params, obs, action_noise)[0],
                random_action)
        with jax.named_scope("env_step"):
            env_state, step = vec.step(runner.env, action)
        with jax.named_scope("replay_add"):
            buffer = rb.add(runner.buffer, Transition(
                obs=obs, action=action, reward=step.reward, next_obs=step.final_obs,
                terminated=step.terminated.astype(jnp.float32)))
        sac = runner.sac
        if config.normalize_observations:  # the statistics of every observation acted on
            sac = sac.replace(actor_params=observation_norm.observe(
                sac.actor_params, obs, config.data_parallel_axis))
        sac, code, metrics = jax.lax.cond(
            learning,
            lambda sac: _learn(agent, source, watched, sac, buffer, k_learn, runner.iteration),
            lambda sac: (sac, jnp.int32(0), {name: nan for name in METRIC_NAMES}), sac)
        if config.stop_when_solved:  # a stopped seed keeps its learner; the update count is shared
            sac = _unless_stopped(runner.stopped, runner.sac, sac).replace(step=sac.step)
            metrics, code = _unless_stopped(
                runner.stopped, ({name: nan for name in metrics}, jnp.int32(0)), (metrics, code))
        non_finite = jnp.where(runner.non_finite == 0, code, runner.non_finite)
        pending = runner.pending
        if points.depth:
            with jax.named_scope("evaluate"):
                pending = points.step_pending(agent, pending)
        metrics["train_return"] = jnp.sum(jnp.where(step.done, step.episode_return, 0.0))
        counts = {name: jnp.isfinite(m).astype(jnp.float32) for name, m in metrics.items()}
        counts["train_return"] = jnp.sum(step.done).astype(jnp.float32)
        sums = _accumulate(runner.sums, metrics, counts)
        return runner.replace(sac=sac, env=env_state, buffer=buffer, key=key, sums=sums,
                              iteration=runner.iteration + 1, non_finite=non_finite,
                              pending=pending)

    def next_boundary(iterations_done: jax.Array) -> jax.Array:
        """The iteration count at which the chunk starting at `iterations_done` ends."""
        periods_done = (iterations_done - prefill) // period
        return jnp.where(iterations_done < prefill, prefill, prefill + (periods_done + 1) * period)

    def advance(runner: RunnerState, max_iterations: Optional[int] = None) -> RunnerState:
        run_agent = agent.with_hyperparams(runner.hyperparams)
        end = next_boundary(runner.iteration)  # a shared counter: one trip count for all seeds
        if max_iterations is not None:
            end = jnp.minimum(end, runner.iteration + max_iterations)
        # every chunk starts and ends on a multiple of `block` (the module docstring)
        block = math.gcd(prefill, period, max_iterations or 0)
        return jax.lax.while_loop(
            lambda r: r.iteration < end,
            lambda r: jax.lax.fori_loop(0, block, lambda _, r: iteration(run_agent, r), r),
            runner)

    def evaluate(runner: RunnerState) -> RunnerState:
        run_agent = agent.with_hyperparams(runner.hyperparams)
        return jax.lax.cond(evaluates_after(runner.iteration),
                            lambda r: evaluate_period(run_agent, r), lambda r: r, runner)

    def record_draws(key: jax.Array) -> Draws:
        def one(key, i):
            key, k_act, k_learn = iteration_keys(key)
            size = jnp.minimum((i + 1) * n, config.buffer_size)  # after this iteration's add
            draws = Draws(*keys.acting(k_act, i), *keys.learning(k_learn, size, i))
            key = jax.lax.cond(evaluates_after(i + 1), lambda k: point_keys(k)[0],
                               lambda k: k, key)
            return key, draws

        return jax.lax.scan(one, init_keys(key)[2], jnp.arange(config.run_iterations))[1]

    def init(key: jax.Array, hyperparams: Optional[Dict[str, jax.Array]] = None) -> RunnerState:
        k_sac, k_env, k_run = init_keys(key)
        env_state = vec.reset(k_env)
        example = Transition(obs=env_state.env_state.obs[0],
                             action=jnp.zeros(agent.action_size, jnp.float32),
                             reward=jnp.float32(0), next_obs=env_state.env_state.obs[0],
                             terminated=jnp.float32(0))
        zero = jnp.float32(0)
        sac = agent.with_hyperparams(hyperparams).init(k_sac)
        # empty slots of evaluations under way (never stepped while empty, nor scored, so any
        # states will do)
        pending = points.init_pending(jax.random.fold_in(k_env, 1), sac.actor_params)
        return RunnerState(
            sac=sac, env=env_state, buffer=rb.init(config.buffer_size, example),
            key=k_run, iteration=jnp.int32(0), sums={name: (zero, zero) for name in sum_names},
            outputs={"env_steps": jnp.zeros(config.num_evals, jnp.int32),
                     **{name: jnp.full(config.num_evals, jnp.nan, jnp.float32)
                        for name in sum_names + EVAL_NAMES}},
            delivered=selection.init(sac.actor_params), stopped=jnp.bool_(False),
            non_finite=jnp.int32(0), hyperparams=hyperparams, pending=pending)

    return TrainParts(init, advance, evaluate, config.run_iterations,
                      (prefill > 0) + config.num_evals, record_draws)


def record_draws(config: SACConfig, key: jax.Array) -> Draws:
    """The random draws `make_train(config)(key)` makes, iteration by iteration: a `Draws` with
    a leading axis T = prefill_iterations + num_evals * iterations_per_eval. Replayed
    (`make_train(config, randomness=replay(config, draws))`), it gives the same run as
    `train(key)`; feeding it to another implementation replays the run there (batch_index are
    slots of the ring buffer, filled num_envs at a time in order from slot 0). Pure and
    jit-able."""
    return make_train_parts(config).record_draws(key)


def replay(config: SACConfig, draws: Draws) -> Replay:
    """The recorded stream `draws` as the randomness of `make_train(config, randomness=...)`;
    ValueError naming the first field whose shape differs from what `record_draws(config,
    key)` makes."""
    check(draws, jax.eval_shape(lambda key: record_draws(config, key), jax.random.key(0)))
    return Replay(draws)


def make_train(config: SACConfig,
               progress: Optional[Callable[[Dict[str, jax.Array]], None]] = None,
               randomness=None, seed_axis: Optional[str] = None):
    """Returns `train(key, hyperparams=None) -> (RunnerState, metrics)`, the whole run as one
    scan. `hyperparams`: {name: scalar} values to train with in place of the config's, traced
    (`sac_jax.hyperparams`; `jax.vmap(train)(keys, hyperparams.stack(configs))` trains many
    settings in one program).

    metrics: arrays with a leading axis of `config.num_evals` evaluation points:
    `env_steps` (environment steps done), `eval_return`, `confirm_return`, `kept_return`,
    `delivered_return` and `stopped` (`EVAL_NAMES`), `train_return` (mean return of training
    episodes ended in the period, NaN if none), and the period means of the update metrics in
    `METRIC_NAMES` (NaN where unused, and after a seed stopped). The runner's
    `delivered.actor_params` is the actor the run delivers (`sac_jax.selection`).
    `randomness`, if given, is the source of acting's and learning's draws
    (`sac_jax.randomness`; e.g. `replay(config, record_draws(config, key))`), default the
    run's PRNG keys.
    `progress`, if given, is called on the host with each evaluation point's metrics (through
    `jax.debug.callback`; under `vmap` once per seed). A program with a host callback is not
    kept by JAX's persistent compilation cache; `sac_jax.run` reports progress between chunks.
    `seed_axis`: the name of the `vmap` axis `train` runs under, if any (`jax.vmap(train,
    axis_name=seed_axis)`): fresh environment states are then computed on the iterations where
    some seed's episode ended, not at every iteration (`envs.VectorEnv`'s `reset_axis`), for
    the same values up to float rounding (bit for bit in 2-seed runs of `fast` and
    `CartpoleBalance` on a CPU).
    """
    parts = make_train_parts(config, progress, randomness, seed_axis)

    def train(key: jax.Array, hyperparams: Optional[Dict[str, jax.Array]] = None):
        runner = jax.lax.scan(lambda r, _: (parts.chunk(r), None), parts.init(key, hyperparams),
                              None, length=parts.num_chunks)[0]
        return runner, runner.outputs

    return train
