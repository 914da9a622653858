"""Environment-step throughput of InvertedPendulum-v5: MJX vs Gymnasium vs mujoco.rollout.

MJX: ``jit`` of a ``lax.scan`` over ``--steps`` steps of ``VectorEnv.step`` (vmapped step
with auto-reset) with uniform random actions, for each ``--sizes`` instance count.  Compile
time is measured separately (``jit(...).lower(...).compile()``); run time is the median of
``--repeats`` calls of the compiled function. ``--lean-stages on|off`` sets the environment's
`envs.mjx_env.MjxEnv.lean_stages` (default: the platform's choice, lean except on a CPU);
``--lean-stages off on`` measures every size both ways in one call.

Baselines on the same machine:
* Gymnasium's C-MuJoCo ``InvertedPendulum-v5`` stepped in a Python loop (one instance,
  random actions, reset on termination/truncation);
* ``mujoco.rollout`` (C MuJoCo, multi-threaded, open loop, no resets): ``frame_skip`` = 2
  physics steps count as one environment step.

One environment step = 2 RK4 physics steps of 0.02 s.  Prints one markdown table row per
measurement and writes them all to benchmarks/results/NAME.json (`--name`, default
env_throughput-KIND: env_throughput-cpu, env_throughput-h100; command, machine, versions, date).
Example (small, CPU): ``python -m benchmarks.env_throughput --sizes 1024 16384 --steps 100``.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time

import jax
import mujoco
import numpy as np

import envs
from benchmarks.provenance import provenance, result_name, write_result

ENV = "InvertedPendulum-v5"
FRAME_SKIP = 2


def _median_seconds(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def bench_mjx(num_envs: int, steps: int, repeats: int, lean_stages=None
              ) -> tuple[float, float]:
    """(compile seconds, median run seconds) of ``steps`` vector steps of ``num_envs``."""
    env = envs.make(ENV)
    env.lean_stages = lean_stages
    vec = envs.VectorEnv(env, num_envs)
    low, high = vec.env.action_low, vec.env.action_high

    def body(carry, _):
        vstate, key = carry
        key, action_key = jax.random.split(key)
        shape = (num_envs, vec.env.action_size)
        actions = jax.random.uniform(action_key, shape, minval=low, maxval=high)
        vstate, out = vec.step(vstate, actions)
        return (vstate, key), out.reward.sum()

    def run(key):
        key, reset_key = jax.random.split(key)
        carry, rewards = jax.lax.scan(body, (vec.reset(reset_key), key), None, length=steps)
        return carry[0].env_state.obs, rewards.sum()

    key = jax.random.key(0)
    start = time.perf_counter()
    compiled = jax.jit(run).lower(key).compile()
    compile_s = time.perf_counter() - start
    jax.block_until_ready(compiled(key))  # warm-up
    return compile_s, _median_seconds(lambda: jax.block_until_ready(compiled(key)), repeats)


def bench_gymnasium(steps: int, repeats: int) -> float:
    """Median seconds of ``steps`` Python-loop steps of Gymnasium's env."""
    import gymnasium as gym  # a test extra; absent on GPU machines run with --skip-baselines

    env = gym.make(ENV)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-3, 3, (steps, 1)).astype(np.float32)

    def loop():
        env.reset(seed=0)
        for action in actions:
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset()

    return _median_seconds(loop, repeats)


def bench_rollout(num_envs: int, steps: int, repeats: int, threads: int) -> float:
    """Median seconds of ``mujoco.rollout`` of ``num_envs`` × ``steps`` env steps."""
    from mujoco import rollout

    model = envs.make(ENV).mj_model
    data = [mujoco.MjData(model) for _ in range(threads)]
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data[0], state0, spec)
    rng = np.random.default_rng(0)
    initial = np.tile(state0, (num_envs, 1))
    control = rng.uniform(-3, 3, (num_envs, steps * FRAME_SKIP, 1))
    return _median_seconds(lambda: rollout.rollout(model, data, initial, control), repeats)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1024, 16384, 131072])
    parser.add_argument("--steps", type=int, default=1000, help="env steps per instance (MJX)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--gym-steps", type=int, default=20000)
    parser.add_argument("--rollout-steps", type=int, default=100, help="env steps per instance")
    parser.add_argument("--threads", type=int, default=os.cpu_count())
    parser.add_argument("--skip-baselines", action="store_true")
    parser.add_argument("--lean-stages", choices=["auto", "on", "off"], nargs="+",
                        default=["auto"], help="one or more: every size is measured each way")
    parser.add_argument("--name", default=None, help="results file benchmarks/results/NAME.json "
                        "(default env_throughput-KIND)")
    args = parser.parse_args()
    source = provenance()

    print(f"machine: {platform.node()} {platform.machine()} {os.cpu_count()} CPUs; "
          f"jax {jax.__version__} devices {jax.devices()}; mujoco {mujoco.__version__}\n")
    print("| backend | instances | steps/instance | compile s | run s (median) | env steps/s |")
    print("|---|---:|---:|---:|---:|---:|")

    rows = []

    def row(backend, n, steps, compile_s, run_s, lean_stages=None):
        compile_txt = "-" if compile_s is None else f"{compile_s:.1f}"
        rate = n * steps / run_s
        label = backend + (f", lean stages {lean_stages}" if lean_stages else "")
        print(f"| {label} | {n} | {steps} | {compile_txt} | {run_s:.3f} | {rate:,.0f} |",
              flush=True)
        rows.append({"backend": backend, "lean_stages": lean_stages, "instances": n,
                     "steps": steps,
                     "compile_s": None if compile_s is None else round(compile_s, 2),
                     "run_s": round(run_s, 5), "env_steps_per_s": round(rate, 1)})

    for lean_stages in args.lean_stages:
        lean = {"auto": None, "on": True, "off": False}[lean_stages]
        if lean is None:  # the platform's choice, as the environment makes it
            lean_stages = "on" if envs.make(ENV)._uses_lean_stages() else "off"
        for n in args.sizes:
            row(f"MJX lax.scan ({jax.default_backend()})", n, args.steps,
                *bench_mjx(n, args.steps, args.repeats, lean), lean_stages=lean_stages)
    if not args.skip_baselines:
        row("Gymnasium C MuJoCo, Python loop", 1, args.gym_steps, None,
            bench_gymnasium(args.gym_steps, args.repeats))
        for n in args.sizes:
            row(f"mujoco.rollout ({args.threads} threads, no resets)", n, args.rollout_steps,
                None, bench_rollout(n, args.rollout_steps, args.repeats, args.threads))
    default = "on" if envs.make(ENV)._uses_lean_stages() else "off"  # the platform's choice
    write_result(args.name or result_name("env_throughput"),
                 {"env": ENV, "repeats": args.repeats, "default_lean_stages": default,
                  "rows": rows}, source)


if __name__ == "__main__":
    main()
