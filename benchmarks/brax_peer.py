"""Brax's own SAC trainer vs ours, on the same physics, in one process on one machine.

(a) `brax.training.agents.sac.train` on `envs.to_brax(envs.make("InvertedPendulum-v5"))` under
    Brax's own training wrappers (episode_length 1000 = our time limit);
(b) ours: `sac_jax.run.run_training` with the `fast` preset.

Brax's `sac.train` arguments are set from the preset wherever an argument exists:

    num_envs = num_envs (8)              grad_updates_per_step = updates_per_step (4)
    batch_size = batch_size (256)        learning_rate = actor_lr = critic_lr (3e-3)
    discounting = gamma (0.99)           tau = tau (0.02)
    reward_scaling = reward_scale (1)    min_replay_size = learning_starts (1,024)
    max_replay_size = buffer_size        num_eval_envs = eval_episodes (5)
    deterministic_eval = True            normalize_observations = False
    network_factory: hidden sizes actor_hidden = critic_hidden (64, 64), ReLU
    num_timesteps = learning_starts + num_evals * eval_every (the steps ours runs) and
    num_evals = num_evals + 1 (Brax also evaluates at step 0), which puts Brax's evaluations at
    the same environment steps as ours (checked below).

What Brax's trainer fixes and we cannot match: the temperature's Adam step 3e-4 (ours 1e-3),
target entropy -|A|/2 (ours -|A|), update order alpha -> Q -> pi with no policy delay, its
policy head (softplus scale + 0.001) and LeCun-uniform kernels, prefill with the initial policy
(ours: uniform random actions), auto-reset to each environment's first state (ours: a fresh
random state), and truncated transitions masked out of the critic loss (ours bootstrap them).

Measured per trainer, with the same clock for both:
* compile_s: union of the time spans of JAX's tracing, lowering and XLA-compilation events
  (jax.monitoring) during the run; nested traces are counted once.
* solve_total_s: from the trainer's call to the first point at which the policy the trainer
  delivers is solved (950, the task's solved return, envs.spec): ours, the first point whose
  delivered (kept) actor's score reaches it (`sac_jax.selection`; the `fast` preset then
  stops); Brax, which returns its last policy, the first evaluation reaching it
  (`solve_first_eval`: optimistic, as its later evaluations may fall) and whether its last
  evaluation is solved (`final_eval_return`). solve_train_s: the same minus the compile time
  before it.
* env_steps_per_s: environment steps to that point / solve_train_s, evaluations included for
  both (of the whole run where it is not solved). Both sides over the same steps: ours stops
  there, and Brax's evaluations after it step full 1,000-step episodes, which would count
  against its rate (before 2026-11-30 Brax's was over its whole run).
Ratios are ours / brax (time: below 1 means ours is faster; steps/s: above 1).

The persistent compilation cache is off unless --cache-dir is given (then both use it).
Brax 0.14.2 calls `jax.device_put_replicated`, gone since JAX 0.10; this script puts back an
equivalent (`device_put_replicated` below), for this script only.

    python -m benchmarks.brax_peer                        # fast preset, seed 0, JSON line
    python -m benchmarks.brax_peer --seeds 3              # seeds 0..2, medians
    JAX_PLATFORMS=cpu python -m benchmarks.brax_peer      # CPU on a GPU machine
    python -m benchmarks.brax_peer --quick                # tiny run: checks the script only

The JSON line is also written to benchmarks/results/NAME.json (`--name`, default brax_peer-KIND:
brax_peer-h100, brax_peer-cpu; command, machine, versions, date).
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import platform
import statistics
import sys
import time


import jax
import jax.numpy as jnp

import envs
from benchmarks.provenance import provenance, result_name, write_result
from sac_jax.presets import PRESETS
from sac_jax.run import compiled_program, run_training

COMPILE_EVENTS = ("/jax/core/compile/jaxpr_trace_duration",
                  "/jax/core/compile/jaxpr_to_mlir_module_duration",
                  "/jax/core/compile/backend_compile_duration")
QUICK = dict(total_steps=768, learning_starts=256, buffer_size=768, eval_every=256,
             eval_episodes=2)


def device_put_replicated(x, devices):
    """`jax.device_put_replicated` as JAX had it: the pytree `x` stacked len(devices) times on
    a new leading axis, slice i on devices[i] (a pmap returning `x` on every device)."""
    return jax.pmap(lambda _: x, devices=devices)(jnp.arange(len(devices)))


class CompileClock:
    """Collects (start, end) wall-clock spans of JAX's compile events."""

    def __init__(self):
        self.spans = []
        jax.monitoring.register_event_time_span_listener(self._on_span)

    def _on_span(self, event, start, end, **_):
        if event in COMPILE_EVENTS:
            self.spans.append((start, end))

    def seconds(self, t0: float, t1: float) -> float:
        """Length of the union of the spans clipped to [t0, t1] (time.time() seconds)."""
        total, reach = 0.0, t0
        for start, end in sorted(self.spans):
            start, end = max(start, reach), min(end, t1)
            if end > start:
                total += end - start
                reach = end
        return total


def brax_arguments(config) -> dict:
    """`sac.train` keyword arguments matching `config` (see the module docstring)."""
    from brax.training.agents.sac import networks as sac_networks

    if config.actor_lr != config.critic_lr or config.actor_hidden != config.critic_hidden:
        raise ValueError("Brax's SAC has one learning rate and one hidden-layer spec for both "
                         f"networks; config has actor_lr={config.actor_lr}, critic_lr="
                         f"{config.critic_lr}, actor_hidden={config.actor_hidden}, "
                         f"critic_hidden={config.critic_hidden}")
    return dict(
        num_timesteps=config.learning_starts + config.num_evals * config.eval_every,
        num_envs=config.num_envs,
        batch_size=config.batch_size, grad_updates_per_step=config.updates_per_step,
        learning_rate=config.actor_lr, discounting=config.gamma, tau=config.tau,
        reward_scaling=config.reward_scale, min_replay_size=config.learning_starts,
        max_replay_size=config.buffer_size, num_evals=config.num_evals + 1,
        num_eval_envs=config.eval_episodes, deterministic_eval=True,
        normalize_observations=False,
        network_factory=functools.partial(sac_networks.make_sac_networks,
                                          hidden_layer_sizes=config.actor_hidden))


def figures(clock, t0, t_end, points, threshold):
    """Summary of one run from its evaluation points [(env_steps, return, time.time())]."""
    total_steps = points[-1][0]
    compile_s = clock.seconds(t0, t_end)
    solved = next(((s, t) for s, r, t in points if r >= threshold), None)
    out = dict(compile_s=round(compile_s, 2), wall_s=round(t_end - t0, 2),
               total_steps=total_steps, eval_steps=[s for s, _, _ in points],
               eval_returns=[round(r, 1) for _, r, _ in points],
               env_steps_per_s=round(total_steps / (t_end - t0 - compile_s), 1),
               solved_at_step=None, solve_total_s=None, solve_train_s=None)
    if solved is not None:
        step, t = solved
        train_s = t - t0 - clock.seconds(t0, t)
        out.update(solved_at_step=step, solve_total_s=round(t - t0, 2),
                   solve_train_s=round(train_s, 2), env_steps_per_s=round(step / train_s, 1))
    return out


def run_brax(config, seed, clock, threshold):
    from brax.training.agents.sac import train as brax_sac

    env = envs.to_brax(config.make_env())
    points = []

    def progress(step, metrics):
        if step > 0:  # Brax's evaluation before training
            points.append((int(step), float(metrics["eval/episode_reward"]), time.time()))

    t0 = time.time()
    brax_sac.train(environment=env, episode_length=env.max_episode_steps, seed=seed,
                   progress_fn=progress, **brax_arguments(config))
    return figures(clock, t0, time.time(), points, threshold)


def run_ours(config, seed, clock, threshold):
    points = []

    def on_point(step, metrics, _returns, _elapsed):
        points.append((int(step), float(metrics["delivered_return"]), time.time()))

    compiled_program.cache_clear()  # every seed compiles, as Brax's trainer does
    t0 = time.time()
    run_training(config, seeds=1, seed=seed, on_point=on_point)
    return figures(clock, t0, time.time(), points, threshold)


def ratio(a, b):
    return None if a is None or b is None or b == 0 else round(a / b, 3)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--preset", default="fast", choices=sorted(PRESETS))
    parser.add_argument("--total-steps", type=int, default=None,
                        help="environment steps per run (default: the preset's)")
    parser.add_argument("--seeds", type=int, default=1, help="seeds 0..N-1, one run each")
    parser.add_argument("--cache-dir", default=None,
                        help="use JAX's persistent compilation cache in this directory")
    parser.add_argument("--quick", action="store_true",
                        help=f"tiny runs {QUICK} to check the script (figures meaningless)")
    parser.add_argument("--name", default=None, help="results file benchmarks/results/NAME.json "
                        "(default brax_peer-KIND: brax_peer-h100, brax_peer-cpu)")
    args = parser.parse_args()
    source = provenance()
    if args.seeds < 1:
        parser.error(f"--seeds must be >= 1, got {args.seeds}")

    config = PRESETS[args.preset]
    if args.quick:
        config = config.replace(**QUICK)
    if args.total_steps is not None:
        config = config.replace(total_steps=args.total_steps,
                                buffer_size=max(config.buffer_size, args.total_steps))
    threshold = envs.spec(config.env).solved_return
    if args.cache_dir:
        from sac_jax.compilation_cache import enable_compilation_cache
        enable_compilation_cache(args.cache_dir)
    else:
        jax.config.update("jax_enable_compilation_cache", False)
    if not hasattr(jax, "device_put_replicated"):
        jax.device_put_replicated = device_put_replicated

    clock = CompileClock()
    jax.block_until_ready(jax.jit(lambda x: x + 1)(jnp.zeros(())))  # backend start-up
    runs = []
    for seed in range(args.seeds):
        brax_run = run_brax(config, seed, clock, threshold)
        ours_run = run_ours(config, seed, clock, threshold)
        ours_steps = ours_run["eval_steps"]  # ours stops once solved: a prefix of Brax's
        if brax_run["eval_steps"][:len(ours_steps)] != ours_steps:
            raise SystemExit(f"evaluation points differ: brax {brax_run['eval_steps']}, "
                             f"ours {ours_steps}")
        brax_run["final_eval_return"] = brax_run["eval_returns"][-1]
        runs.append(dict(seed=seed, brax=brax_run, ours=ours_run))
        print(f"seed {seed}: brax {brax_run}\n        ours {ours_run}", file=sys.stderr,
              flush=True)

    keys = ("compile_s", "solve_total_s", "solve_train_s", "env_steps_per_s")

    def median(who, key):
        values = [r[who][key] for r in runs]
        return None if None in values else statistics.median(values)

    medians = {who: {k: median(who, k) for k in keys} for who in ("brax", "ours")}
    import brax

    result = dict(
        benchmark="brax_peer", env=config.env, preset=args.preset, quick=args.quick,
        total_steps=config.total_steps, solved_return=threshold, seeds=args.seeds,
        device=str(jax.devices()[0].device_kind), platform=jax.default_backend(),
        machine=platform.machine(), cpus=os.cpu_count(), jax=jax.__version__,
        brax=brax.__version__, median=medians,
        ratio_ours_over_brax={k: ratio(medians["ours"][k], medians["brax"][k]) for k in keys},
        runs=runs)
    print(json.dumps(result))
    write_result(args.name or result_name("brax_peer"), result, source)


if __name__ == "__main__":
    main()
