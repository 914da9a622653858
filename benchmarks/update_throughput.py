"""Gradient-update throughput: `sac_jax.sac_update` vs the PyTorch seed-002 update, same run.

Both run the `cleanrl` preset's sizes (batch 256, 256x256 networks, policy delay 2) on
InvertedPendulum-v4 shapes, sampling each batch from a replay buffer of random transitions:
ours as a jitted `lax.scan` of `--updates` updates on device; PyTorch as CleanRL's Python loop
(numpy index sampling, tensor gather, `update`). Also reported: FLOPs of one update from XLA's
cost analysis, the matmul rate JAX reaches on this machine (a 1024^3 product), and the fraction
of that roofline our update reaches. Each figure is the median of `--repeats` timings.

    python benchmarks/update_throughput.py --updates 500 --repeats 3
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

import sac_jax  # noqa: E402
from sac_jax import replay_buffer as rb  # noqa: E402
from tests.reference.cleanrl_sac import CleanRLSAC, make_batch  # noqa: E402

OBS, ACT, CAPACITY = 4, 1, 100_000


def median_time(fn, repeats):
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def random_data(rng):
    return dict(obs=rng.normal(size=(CAPACITY, OBS)).astype(np.float32),
                action=rng.uniform(-3, 3, size=(CAPACITY, ACT)).astype(np.float32),
                reward=np.ones(CAPACITY, np.float32),
                next_obs=rng.normal(size=(CAPACITY, OBS)).astype(np.float32),
                terminated=(rng.uniform(size=CAPACITY) < 0.01).astype(np.float32))


def jax_updates_per_s(config, data, updates, repeats):
    agent = sac_jax.make_agent(config, OBS, ACT, -3.0, 3.0)
    buffer = rb.ReplayBuffer(data=sac_jax.Transition(**{k: jnp.asarray(v) for k, v in data.items()}),
                             position=jnp.int32(0), size=jnp.int32(CAPACITY))

    def run(state, key):
        def one(state, key):
            k_batch, k_noise = jax.random.split(key)
            batch = rb.sample(buffer, k_batch, config.batch_size)
            return sac_jax.sac_update(agent, state, batch, k_noise)[0], None
        return jax.lax.scan(one, state, jax.random.split(key, updates))[0]

    state = agent.init(jax.random.key(0))
    run = jax.jit(run)
    jax.block_until_ready(run(state, jax.random.key(1)))  # compile and warm up
    seconds = median_time(lambda: jax.block_until_ready(run(state, jax.random.key(2))), repeats)
    single = jax.jit(sac_jax.sac_update).lower(
        agent, state, rb.sample(buffer, jax.random.key(0), config.batch_size),
        jax.random.key(0)).compile()
    cost = single.cost_analysis()
    cost = cost[0] if isinstance(cost, (list, tuple)) else cost
    return updates / seconds, float(cost.get("flops", float("nan")))


def torch_updates_per_s(data, updates, repeats):
    ref = CleanRLSAC(OBS, ACT, np.full(ACT, -3.0), np.full(ACT, 3.0))
    rng = np.random.default_rng(0)
    step = {"global": 5000}

    def loop():
        for _ in range(updates):
            idx = rng.integers(0, CAPACITY, 256)
            batch = make_batch(data["obs"][idx], data["action"][idx], data["reward"][idx],
                               data["next_obs"][idx], data["terminated"][idx])
            noise = {"critic": torch.randn(256, ACT),
                     "actor": [torch.randn(256, ACT) for _ in range(2)],
                     "temperature": [torch.randn(256, ACT) for _ in range(2)]}
            step["global"] += 1
            ref.update(batch, noise, step["global"])

    loop()  # warm up
    return updates / median_time(loop, repeats)


def matmul_flops_per_s(repeats, n=1024):
    a = jax.random.normal(jax.random.key(0), (n, n))
    f = jax.jit(lambda a: a @ a)
    jax.block_until_ready(f(a))
    return 2 * n ** 3 / median_time(lambda: jax.block_until_ready(f(a)), repeats * 5)


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--updates", type=int, default=500)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    config = sac_jax.PRESETS["cleanrl"]
    data = random_data(np.random.default_rng(0))
    ours, flops = jax_updates_per_s(config, data, args.updates, args.repeats)
    theirs = torch_updates_per_s(data, args.updates, args.repeats)
    peak = matmul_flops_per_s(args.repeats)
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"jax {jax.__version__} on {jax.devices()[0].platform}, torch {torch.__version__} "
          f"({torch.get_num_threads()} threads)")
    print("| implementation | updates/s | ratio |")
    print("| --- | ---: | ---: |")
    print(f"| sac_jax sac_update (scan) | {ours:.1f} | {ours / theirs:.2f}x |")
    print(f"| PyTorch seed-002 loop | {theirs:.1f} | 1.00x |")
    print(f"FLOPs per update (XLA cost analysis): {flops / 1e6:.0f} M; JAX matmul rate "
          f"{peak / 1e9:.1f} GFLOP/s; ours reaches {ours * flops / peak:.0%} of that roofline")


if __name__ == "__main__":
    main()
