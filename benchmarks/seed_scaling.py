"""Gradient updates/s of `sac_update` for many seeds vmapped in one program (the `fast` preset's
networks and batch unless overridden), each seed sampling its own batches from its own buffer.

    python -m benchmarks.seed_scaling --seeds 1 16 256 1024 --updates 200 [--hidden-dtype bfloat16]
    python -m benchmarks.seed_scaling --seeds 1 256 --hidden-dtype float32 bfloat16   # both

Every seed count is measured with every `--hidden-dtype` given; all rows are written to
benchmarks/results/NAME.json (`--name`, default seed_scaling-KIND: seed_scaling-cpu,
seed_scaling-h100; command, machine, versions, date).
"""

from __future__ import annotations

import argparse
import statistics
import time


import jax
import jax.numpy as jnp

import sac_jax
from benchmarks.provenance import provenance, result_name, write_result
from sac_jax import replay_buffer as rb

CAPACITY = 20_480


def updates_per_s(config, seeds, updates, repeats):
    agent, _ = sac_jax.train.agent_for(config)
    o, a = agent.observation_size, agent.action_size

    def run(key):
        k_data, k_init, k_run = jax.random.split(key, 3)
        data = sac_jax.Transition(
            obs=jax.random.normal(k_data, (CAPACITY, o)), action=jnp.zeros((CAPACITY, a)),
            reward=jnp.ones(CAPACITY), next_obs=jax.random.normal(k_data, (CAPACITY, o)),
            terminated=jnp.zeros(CAPACITY))
        buffer = rb.ReplayBuffer(data, jnp.int32(0), jnp.int32(CAPACITY))

        def one(state, key):
            k_batch, k_noise = jax.random.split(key)
            batch = rb.sample(buffer, k_batch, config.batch_size)
            return sac_jax.sac_update(agent, state, batch, k_noise)[0], None

        state = jax.lax.scan(one, agent.init(k_init), jax.random.split(k_run, updates))[0]
        # A result that depends on every parameter, so no update can be optimised away.
        return sum(jnp.sum(x) for x in jax.tree_util.tree_leaves(
            (state.actor_params, state.critic_params)))

    f = jax.jit(jax.vmap(run))
    keys = jax.random.split(jax.random.key(0), seeds)
    t = time.perf_counter()
    jax.block_until_ready(f(keys))
    compile_and_first = time.perf_counter() - t
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        jax.block_until_ready(f(keys))
        times.append(time.perf_counter() - t)
    return seeds * updates / statistics.median(times), compile_and_first


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--preset", default="fast")
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 16, 256, 1024])
    parser.add_argument("--updates", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--hidden-dtype", nargs="+", default=["float32"],
                        help="SACConfig.hidden_dtype: one or more (each seed count with each)")
    parser.add_argument("--name", default=None, help="results file benchmarks/results/NAME.json "
                        "(default seed_scaling-KIND)")
    args = parser.parse_args()
    source = provenance()
    preset = sac_jax.PRESETS[args.preset]
    print(f"jax {jax.__version__} on {jax.devices()[0].device_kind}; preset {args.preset}: "
          f"batch {preset.batch_size}, actor {preset.actor_hidden}, critic {preset.critic_hidden}")
    print("| hidden layers | seeds | updates/s (all seeds) | updates/s per seed | "
          "compile + first run s |")
    print("| --- | ---: | ---: | ---: | ---: |")
    rows = []
    for seeds in args.seeds:
        for dtype in args.hidden_dtype:
            config = preset.replace(hidden_dtype=dtype)
            rate, first = updates_per_s(config, seeds, args.updates, args.repeats)
            print(f"| {dtype} | {seeds} | {rate:,.0f} | {rate / seeds:,.0f} | {first:.1f} |",
                  flush=True)
            rows.append({"hidden_dtype": dtype, "seeds": seeds, "updates_per_s": round(rate, 1),
                         "compile_and_first_s": round(first, 2)})
    write_result(args.name or result_name("seed_scaling"), {
        "preset": args.preset, "batch_size": preset.batch_size,
        "actor_hidden": list(preset.actor_hidden), "critic_hidden": list(preset.critic_hidden),
        "updates": args.updates, "repeats": args.repeats, "rows": rows}, source)

if __name__ == "__main__":
    main()
