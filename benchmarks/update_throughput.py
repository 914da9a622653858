"""Gradient-update throughput: `sac_jax.sac_update` vs the PyTorch seed-002 update, and the
roofline, measured side by side in one run.

Both run the `cleanrl` preset's sizes (batch 256, 256x256 networks, policy delay 2) on
InvertedPendulum-v4 shapes, sampling each batch from a replay buffer of random transitions:
ours as a jitted `lax.scan` of `--updates` updates on device; PyTorch as CleanRL's Python loop
(numpy index sampling, tensor gather, `update`) of as many updates.

Roofline: FLOPs of one update from XLA's cost analysis, times updates/s, against two matmul
rates JAX reaches on this machine: a 1024^3 product (the machine's matmul roofline, best of 5
calls) and a chain of 200 products at the update's own layer shape (batch x width by width x
width, here 256^3).

All four are timed in alternation, `--rounds` rounds, and the ratios are formed within each
round before the median is taken: the load of a shared machine drifts over seconds (this VM's
1024^3 rate ranged 85-167 GFLOP/s between runs), and what drifts cancels out of a ratio of
timings taken moments apart.

    python -m benchmarks.update_throughput --updates 100 --rounds 10

Writes every round and the medians to benchmarks/results/NAME.json (`--name`, default
update_throughput-KIND: update_throughput-cpu; command, machine, versions, date).
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import os
import platform
import statistics
import time


import jax
import jax.numpy as jnp
import numpy as np
import torch

import sac_jax
from sac_jax import replay_buffer as rb
from benchmarks.provenance import provenance, result_name, write_result
from references.cleanrl_sac import CleanRLSAC, make_batch

OBS, ACT, CAPACITY = 4, 1, 100_000


def seconds(fn, calls=1):
    """The shortest of `calls` timings of fn()."""
    best = float("inf")
    for _ in range(calls):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def random_data(rng):
    return dict(obs=rng.normal(size=(CAPACITY, OBS)).astype(np.float32),
                action=rng.uniform(-3, 3, size=(CAPACITY, ACT)).astype(np.float32),
                reward=np.ones(CAPACITY, np.float32),
                next_obs=rng.normal(size=(CAPACITY, OBS)).astype(np.float32),
                terminated=(rng.uniform(size=CAPACITY) < 0.01).astype(np.float32))


def jax_updates(config, data, updates):
    """(FLOPs of one `sac_update`, `run()` doing `updates` updates in one jitted scan on batches
    sampled from a buffer of `data`, compiled and warmed up)."""
    agent = sac_jax.make_agent(config, OBS, ACT, -3.0, 3.0)
    buffer = rb.ReplayBuffer(data=sac_jax.Transition(**{k: jnp.asarray(v) for k, v in data.items()}),
                             position=jnp.int32(0), size=jnp.int32(CAPACITY))

    def scanned(state, key):
        def one(state, key):
            k_batch, k_noise = jax.random.split(key)
            batch = rb.sample(buffer, k_batch, config.batch_size)
            return sac_jax.sac_update(agent, state, batch, k_noise)[0], None
        return jax.lax.scan(one, state, jax.random.split(key, updates))[0]

    state = agent.init(jax.random.key(0))
    scanned = jax.jit(scanned)
    jax.block_until_ready(scanned(state, jax.random.key(1)))  # compile and warm up
    calls = itertools.count()
    return (update_flops(config, buffer), lambda: jax.block_until_ready(
        scanned(state, jax.random.fold_in(jax.random.key(2), next(calls)))))


def update_flops(config, buffer) -> float:
    """FLOPs of one `sac_update` call on average over K = policy_frequency calls: the critic
    step, and the actor block's K actor (and temperature) steps once in K calls, so one actor
    step per call. That is one update of the same config with K = 1, whose cost XLA counts
    straight: of K > 1 it would count the `lax.cond` around the actor block as if it ran every
    call and the block's `lax.scan` body once, not K times (XLA's cost analysis)."""
    config = dataclasses.replace(config, policy_frequency=1)
    agent = sac_jax.make_agent(config, OBS, ACT, -3.0, 3.0)
    single = jax.jit(sac_jax.sac_update).lower(
        agent, agent.init(jax.random.key(0)),
        rb.sample(buffer, jax.random.key(0), config.batch_size), jax.random.key(0)).compile()
    cost = single.cost_analysis()
    cost = cost[0] if isinstance(cost, (list, tuple)) else cost
    return float(cost.get("flops", float("nan")))


def torch_updates(data, updates):
    """`run()` doing `updates` PyTorch seed-002 updates the CleanRL way, warmed up."""
    ref = CleanRLSAC(OBS, ACT, np.full(ACT, -3.0), np.full(ACT, 3.0))
    rng = np.random.default_rng(0)
    step = {"global": 5000}

    def run():
        for _ in range(updates):
            idx = rng.integers(0, CAPACITY, 256)
            batch = make_batch(data["obs"][idx], data["action"][idx], data["reward"][idx],
                               data["next_obs"][idx], data["terminated"][idx])
            noise = {"critic": torch.randn(256, ACT),
                     "actor": [torch.randn(256, ACT) for _ in range(2)],
                     "temperature": [torch.randn(256, ACT) for _ in range(2)]}
            step["global"] += 1
            ref.update(batch, noise, step["global"])

    run()
    return run


def matmuls(config):
    """(1024^3 product, its FLOPs), (chain of 200 products at the layer shape, its FLOPs), each
    as a warmed-up `run()`."""
    big = jax.random.normal(jax.random.key(0), (1024, 1024))
    square = jax.jit(lambda a: a @ a)
    b, width = config.batch_size, config.critic_hidden[0]
    x = jax.random.normal(jax.random.key(1), (b, width))
    w = jax.random.normal(jax.random.key(2), (width, width)) / width ** 0.5
    chain = jax.jit(lambda x: jax.lax.scan(lambda x, _: (jnp.tanh(x @ w), None), x, None,
                                           length=200)[0])
    runs = (lambda: jax.block_until_ready(square(big)), lambda: jax.block_until_ready(chain(x)))
    for run in runs:
        run()
    return (runs[0], 2 * 1024 ** 3), (runs[1], 200 * 2 * b * width ** 2)


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--updates", type=int, default=100, help="updates per timing")
    parser.add_argument("--rounds", type=int, default=10)
    parser.add_argument("--name", default=None, help="results file benchmarks/results/NAME.json "
                        "(default update_throughput-KIND)")
    args = parser.parse_args()
    source = provenance()
    config = sac_jax.PRESETS["cleanrl"]
    data = random_data(np.random.default_rng(0))
    flops, ours_run = jax_updates(config, data, args.updates)
    theirs_run = torch_updates(data, args.updates)
    (square, square_flops), (chain, chain_flops) = matmuls(config)
    rounds = []
    for _ in range(args.rounds):
        ours = args.updates / seconds(ours_run)
        theirs = args.updates / seconds(theirs_run)
        peak = square_flops / seconds(square, 5)
        layer = chain_flops / seconds(chain)
        rounds.append({"ours": ours, "theirs": theirs, "peak": peak, "layer": layer,
                       "speedup": ours / theirs, "of_peak": ours * flops / peak,
                       "of_layer": ours * flops / layer})
    med = {name: statistics.median(r[name] for r in rounds) for name in rounds[0]}
    low = {name: min(r[name] for r in rounds) for name in rounds[0]}
    high = {name: max(r[name] for r in rounds) for name in rounds[0]}
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"jax {jax.__version__} on {jax.devices()[0].platform}, torch {torch.__version__} "
          f"({torch.get_num_threads()} threads); {args.rounds} rounds of {args.updates} updates")
    print("| figure | median | range over rounds |")
    print("| --- | ---: | ---: |")
    for name, label, fmt in [
            ("ours", "sac_jax `sac_update` (scan), updates/s", "{:.1f}"),
            ("theirs", "PyTorch seed-002 loop, updates/s", "{:.1f}"),
            ("speedup", "ours / PyTorch (per round)", "{:.2f}x"),
            ("peak", "JAX 1024^3 matmul, GFLOP/s", "{:.1f}"),
            ("layer", "JAX chain at the layer shape, GFLOP/s", "{:.1f}"),
            ("of_peak", "ours / 1024^3 roofline (per round)", "{:.0%}"),
            ("of_layer", "ours / layer-shape rate (per round)", "{:.0%}")]:
        scale = 1e-9 if name in ("peak", "layer") else 1
        print(f"| {label} | {fmt.format(med[name] * scale)} | "
              f"{fmt.format(low[name] * scale)} - {fmt.format(high[name] * scale)} |")
    print(f"FLOPs per update (XLA cost analysis): {flops / 1e6:.0f} M")
    write_result(args.name or result_name("update_throughput"), {
        "preset": "cleanrl", "batch_size": config.batch_size,
        "hidden": list(config.critic_hidden), "policy_frequency": config.policy_frequency,
        "updates": args.updates, "rounds": args.rounds, "torch_threads": torch.get_num_threads(),
        "flops_per_update": flops, "median": med, "min": low, "max": high,
        "all_rounds": rounds}, source)


if __name__ == "__main__":
    main()
