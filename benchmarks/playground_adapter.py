"""What the Playground adapter costs, and which backend steps a task faster.

For each task and backend (``--impl jax warp``): a jitted ``lax.scan`` of ``--steps`` steps of
``--envs`` vmapped instances, stepped two ways with the same uniform random actions in the
task's ``ctrlrange``:

* raw      Playground's own ``task.step`` (``registry.load(task, {"impl": impl})``);
* adapter  ``envs.make("playground/<task>", impl=impl).step`` (envs/playground.py: action
           sanitising and clipping, step counter, truncation, termination), no auto-reset.

Run time is the median of ``--repeats`` calls of the compiled scan, the two ways interleaved
so that drift hits both. ``overhead`` = adapter / raw - 1 (the issue-24 target: at most 5 %).
``steps_per_s`` of the raw step per backend is how the default backend is chosen
(envs/playground.py). Writes benchmarks/results/playground_adapter-KIND.json.
Example: ``python -m benchmarks.playground_adapter --tasks CartpoleBalance --steps 200``.
"""

from __future__ import annotations

import argparse
import importlib
import statistics
import time

import jax
import numpy as np

import envs
from benchmarks.provenance import provenance, result_name, write_result

FAMILY = ("CartpoleBalance", "CartpoleSwingup", "PendulumSwingup", "AcrobotSwingup")


def _scan(step, reset, low, high, num_envs: int, steps: int):
    """A jitted f(key) that resets ``num_envs`` states and scans ``steps`` vmapped steps."""
    step, reset = jax.vmap(step), jax.vmap(reset)

    def body(carry, _):
        state, key = carry
        key, action_key = jax.random.split(key)
        action = jax.random.uniform(action_key, (num_envs, low.size), minval=low, maxval=high)
        state = step(state, action)
        return (state, key), state.reward.sum()

    def run(key):
        key, reset_key = jax.random.split(key)
        carry, rewards = jax.lax.scan(
            body, (reset(jax.random.split(reset_key, num_envs)), key), None, length=steps)
        return rewards.sum()

    return jax.jit(run)


def measure(task: str, impl: str, num_envs: int, steps: int, repeats: int) -> dict:
    env = envs.make(envs.playground.PREFIX + task, impl=impl)
    low, high = env.action_low, env.action_high
    runs = {"raw": _scan(env.task.step, env.task.reset, low, high, num_envs, steps),
            "adapter": _scan(env.step, env.reset, low, high, num_envs, steps)}
    key = jax.random.key(0)
    compile_s = {}
    for way, fn in runs.items():
        start = time.perf_counter()
        runs[way] = fn.lower(key).compile()
        compile_s[way] = time.perf_counter() - start
        jax.block_until_ready(runs[way](key))  # warm-up
    times = {way: [] for way in runs}
    for _ in range(repeats):
        for way, fn in runs.items():
            start = time.perf_counter()
            jax.block_until_ready(fn(key))
            times[way].append(time.perf_counter() - start)
    seconds = {way: statistics.median(t) for way, t in times.items()}
    return {"task": task, "impl": impl, "envs": num_envs, "steps": steps,
            "compile_s": compile_s, "seconds": seconds,
            "steps_per_s": {way: num_envs * steps / s for way, s in seconds.items()},
            "overhead": seconds["adapter"] / seconds["raw"] - 1.0}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--tasks", nargs="+", default=list(FAMILY))
    parser.add_argument("--impl", nargs="+", default=["jax"], choices=["jax", "warp"])
    parser.add_argument("--envs", type=int, default=128)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--name", default=None)
    args = parser.parse_args()
    if "warp" in args.impl:  # before MJX, so that it loads its Warp backend (envs/_lean_import.py)
        importlib.import_module("warp")
    source = provenance()
    rows = []
    print("| task | backend | raw steps/s | adapter steps/s | overhead | compile raw / adapter |")
    print("|---|---|---|---|---|---|")
    for task in args.tasks:
        for impl in args.impl:
            row = measure(task, impl, args.envs, args.steps, args.repeats)
            rows.append(row)
            sps, c = row["steps_per_s"], row["compile_s"]
            print(f"| {task} | {impl} | {sps['raw']:,.0f} | {sps['adapter']:,.0f} | "
                  f"{100 * row['overhead']:+.1f} % | {c['raw']:.1f} s / {c['adapter']:.1f} s |",
                  flush=True)
    worst = max(row["overhead"] for row in rows)
    write_result(args.name or result_name("playground_adapter"),
                 {"rows": rows, "worst_overhead": worst,
                  "median_overhead": float(np.median([r["overhead"] for r in rows]))}, source)


if __name__ == "__main__":
    main()
