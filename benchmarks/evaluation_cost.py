"""Seconds of one evaluation of many seeds (`jax.vmap(sac_jax.evaluate)`, 5 episodes each).

    python -m benchmarks.evaluation_cost RUN_DIR [--seeds 1 256] [--repeats 3]
                                         [--lean-stages on off]

RUN_DIR is a finished `scripts/train.py` run whose seed 0 balances InvertedPendulum-v5 (its
episodes last the full 1,000 steps). Three populations of `--seeds` actors, evaluated in one
jitted `vmap` as in a multi-seed training run:

    trained      every seed the trained actor: all episodes run 1,000 steps
    half fallen  even seeds trained, odd seeds freshly initialised (their pendulums fall within
                 a few dozen steps), as in the evaluations of a run whose seeds are half solved
    untrained    every seed freshly initialised: short episodes

and, for the half-fallen population, the earlier loop that stepped ended episodes on from where
they ended (`run_on_evaluate` below, the "before"). Each figure is the median
of `--repeats` timings after a first, compiling call; each population's mean return and longest
episode are printed beside it (both loops give the same). `--lean-stages on|off` sets the
environment's `envs.mjx_env.MjxEnv.lean_stages` (default: the platform's choice). Several
`--seeds` and `--lean-stages` values measure every combination in one call, one JSON line each,
all written to benchmarks/results/NAME.json (`--name`, default evaluation_cost-KIND:
evaluation_cost-cpu, evaluation_cost-h100; command, machine, versions, date).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time


import jax
import jax.numpy as jnp
import numpy as np

import sac_jax
from benchmarks.provenance import provenance, result_name, write_result
from envs.vector import where_rows
from sac_jax.evaluation import initial_states
from sac_jax.train import agent_for

EPISODES = 5


def run_on_evaluate(agent, env, actor_params, key, num_episodes):
    """The evaluation loop before ended episodes were restarted: they step on from where they
    ended (into the pendulum's joint limits) until the last episode ends."""
    def step(carry):
        states, alive, returns = carry
        states = jax.vmap(env.step)(states, agent.act(actor_params, states.obs))
        returns = returns + jnp.where(alive, states.reward, 0.0)
        return states, alive & ~(states.terminated | states.truncated), returns

    init = (initial_states(env, jax.random.split(key, num_episodes)), jnp.ones(num_episodes, bool),
            jnp.zeros(num_episodes, jnp.float32))
    return jax.lax.while_loop(lambda carry: jnp.any(carry[1]), step, init)[2]


def timed(fn, args, repeats):
    start = time.perf_counter()
    returns = np.asarray(jax.block_until_ready(fn(*args)))
    first = time.perf_counter() - start
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - start)
    return {"first_call_s": round(first, 2), "seconds": round(statistics.median(times), 4),
            "longest_episode": int(returns.max()), "mean_return": round(float(returns.mean()), 2)}


def measure(policy, seeds, repeats, lean_stages):
    """The four timings (module docstring) of `seeds` actors with `lean_stages` (on, off, auto)."""
    agent, env = agent_for(policy.config)
    env.lean_stages = {"auto": None, "on": True, "off": False}[lean_stages]
    trained = jax.tree_util.tree_map(lambda x: jnp.broadcast_to(x, (seeds,) + x.shape),
                                     policy.actor_params)
    untrained = jax.vmap(agent.init)(jax.random.split(jax.random.key(5), seeds)).actor_params
    half = where_rows(jnp.arange(seeds) % 2 == 0, trained, untrained)
    keys = jax.random.split(jax.random.key(0), seeds)
    new = jax.jit(jax.vmap(lambda p, k: sac_jax.evaluate(agent, env, p, k, EPISODES)))
    old = jax.jit(jax.vmap(lambda p, k: run_on_evaluate(agent, env, p, k, EPISODES)))
    results = {name: timed(fn, (params, keys), repeats) for name, fn, params in [
        ("trained", new, trained), ("half fallen", new, half),
        ("half fallen, run-on loop", old, half), ("untrained", new, untrained)]}
    return {"seeds": seeds, "episodes_per_seed": EPISODES, "lean_stages": lean_stages,
            "lean_stages_used": env._uses_lean_stages(), **results}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run_dir")
    parser.add_argument("--seeds", type=int, nargs="+", default=[256])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--lean-stages", choices=["auto", "on", "off"], nargs="+",
                        default=["auto"])
    parser.add_argument("--name", default=None, help="results file benchmarks/results/NAME.json "
                        "(default evaluation_cost-KIND)")
    args = parser.parse_args(argv)
    source = provenance()
    policy = sac_jax.load_policy(args.run_dir)
    rows = []
    for seeds in args.seeds:
        for lean_stages in args.lean_stages:
            rows.append(measure(policy, seeds, args.repeats, lean_stages))
            print(json.dumps({"benchmark": "evaluation_cost",
                              "device": jax.devices()[0].device_kind, **rows[-1]}), flush=True)
    write_result(args.name or result_name("evaluation_cost"),
                 {"run_dir": args.run_dir, "preset_env": policy.config.env,
                  "repeats": args.repeats, "rows": rows}, source)


if __name__ == "__main__":
    main()
