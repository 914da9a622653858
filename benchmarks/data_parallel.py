"""Training throughput of one run on one device against the same run data parallel over all
local devices (`sac_jax.parallel.make_data_parallel_parts`).

The configuration is the `fast` preset with the sizes below (global sizes: on D devices each
device steps num_envs/D environments and samples batch_size/D per update). The one-device run
is the ordinary program (`sac_jax.train.make_train_parts`). Each timing is one jitted chunk of
`--iterations` training iterations (after one chunk of random-action prefill and one warm-up
chunk; no evaluation falls in a timed chunk); figures are medians of `--repeats` chunks.
Environment steps/s count transitions (num_envs per iteration); updates/s count global
gradient updates (updates_per_step per iteration, each on the whole batch).
Prints one JSON line and writes it to benchmarks/results/NAME.json (`--name`, default
data_parallel-NUM_ENVS-KIND: data_parallel-262144-2xh200; command, machine, versions, date).

    python -m benchmarks.data_parallel              # 262,144 envs, batch 65,536, 4 updates/iteration
    XLA_FLAGS=--xla_force_host_platform_device_count=2 python -m benchmarks.data_parallel \\
        --num-envs 4 --batch-size 8 --hidden 8 --iterations 2 --repeats 2   # CPU smoke test
"""

from __future__ import annotations

import argparse
import json
import statistics
import time


import jax

from benchmarks.provenance import provenance, result_name, write_result
from sac_jax import PRESETS, parallel
from sac_jax.train import TrainParts, make_train_parts


def benchmark_config(args):
    """The timed run: prefill of one chunk, an evaluation period longer than all timed chunks,
    a buffer that holds every transition."""
    steps_per_chunk = args.num_envs * args.iterations
    period = steps_per_chunk * (args.repeats + 2)
    return PRESETS["fast"].replace(
        env=args.env, num_envs=args.num_envs, batch_size=args.batch_size,
        updates_per_step=args.updates_per_step, actor_hidden=tuple(args.hidden),
        critic_hidden=tuple(args.hidden), learning_starts=steps_per_chunk, eval_every=period,
        total_steps=steps_per_chunk + period,
        buffer_size=args.num_envs * max(args.iterations * (args.repeats + 3),
                                        -(-args.batch_size // args.num_envs)))


def throughput(parts: TrainParts, config, iterations: int, repeats: int) -> dict:
    """Compile seconds and median training throughput of `parts` (see the module docstring)."""
    init = jax.jit(parts.init)
    chunk = jax.jit(lambda r: parts.chunk(r, max_iterations=iterations), donate_argnums=0)
    runner = jax.block_until_ready(init(jax.random.key(0)))
    start = time.perf_counter()
    chunk = chunk.lower(runner).compile()
    compile_s = time.perf_counter() - start
    for _ in range(2):  # prefill, then one training chunk to warm up
        runner = jax.block_until_ready(chunk(runner))
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        runner = jax.block_until_ready(chunk(runner))
        times.append(time.perf_counter() - start)
    seconds = statistics.median(times)
    return {"compile_s": round(compile_s, 2), "chunk_s": round(seconds, 5),
            "env_steps_per_s": round(iterations * config.num_envs / seconds, 1),
            "updates_per_s": round(
                iterations * config.updates_per_step / seconds, 2)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", default="InvertedPendulum-v5")
    parser.add_argument("--num-envs", type=int, default=262144)
    parser.add_argument("--batch-size", type=int, default=65536)
    parser.add_argument("--updates-per-step", type=int, default=4)
    parser.add_argument("--hidden", type=int, nargs="+", default=[256, 256],
                        help="hidden widths of actor and critics")
    parser.add_argument("--iterations", type=int, default=10, help="iterations per timing")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--name", default=None, help="results file benchmarks/results/NAME.json "
                        "(default data_parallel-NUM_ENVS-KIND)")
    args = parser.parse_args(argv)
    source = provenance()
    config = benchmark_config(args)
    devices = jax.local_devices()
    one = throughput(make_train_parts(config), config, args.iterations, args.repeats)
    mesh = parallel.make_mesh(parallel.DATA, devices)
    spread = throughput(parallel.make_data_parallel_parts(config, mesh), config,
                        args.iterations, args.repeats)
    result = {
        "benchmark": "data_parallel", "jax": jax.__version__,
        "device_kind": devices[0].device_kind, "devices": len(devices),
        "config": {"env": config.env, "num_envs": config.num_envs,
                   "batch_size": config.batch_size, "updates_per_step": config.updates_per_step,
                   "hidden": list(config.actor_hidden), "iterations": args.iterations,
                   "repeats": args.repeats},
        "one_device": one, "data_parallel": spread,
        "speedup": round(spread["env_steps_per_s"] / one["env_steps_per_s"], 3)}
    print(json.dumps(result))
    write_result(args.name or result_name(f"data_parallel-{args.num_envs}", all_devices=True),
                 result, source)


if __name__ == "__main__":
    main()
