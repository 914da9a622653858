"""rejax's half of benchmarks/rejax_peer.py, run with the Python of rejax's own virtual
environment (rejax 0.1.3 needs gymnax 0.0.9, which our environment does not pin). It imports
rejax and JAX only, and prints one JSON object on its last line.

Its configuration is rejax's own tuned SAC for Pendulum-v1 (rejax's configs/gymnax/
pendulum.yaml: 1 env, buffer 10,000, fill 256, batch 256, lr 0.01, 1 update per step, 10,000
steps, gamma 0.99, polyak 0.98, swish activations, observation normalisation), evaluated every
`--eval-freq` steps over rejax's 128 episodes. For each `--seeds` count: `jax.jit` of `train`
(vmapped over seeds where more than one), its compile time (`lower(...).compile()`), the median
run time of `--repeats` calls, and per evaluation point the mean return over seeds; for the
first count also `to_result_s`, from this process's start (before JAX is imported) to the end of
its first trained result (imports, JAX's start, compile and the first call): what a user of
rejax waits for one run (rejax_peer.py runs one process per count). rejax keeps no compiled
program between processes; with `--cache-dir` this process turns JAX's persistent compilation
cache on there, as sac-jax's scripts do by default (every compilation cached, however short).

    /path/to/rejax-venv/bin/python benchmarks/rejax_side.py --seeds 1 16
"""

from __future__ import annotations

import time

STARTED = time.perf_counter()

import argparse  # noqa: E402
import importlib.metadata  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402

import jax  # noqa: E402

CONFIG = dict(env="Pendulum-v1", agent_kwargs={"activation": "swish"}, num_envs=1,
              buffer_size=10_000, fill_buffer=256, batch_size=256, learning_rate=0.01,
              num_epochs=1, total_timesteps=10_000, gamma=0.99, polyak=0.98,
              target_entropy_ratio=None, normalize_observations=True)


def timed(train, seeds: int, repeats: int):
    """(compile seconds, [run seconds] of `repeats` calls, the last call's output) of
    `jax.jit(train)` on key 0, vmapped over `seeds` keys split from it where seeds > 1; shared
    with benchmarks/rejax_peer.py, so both trainers are timed alike. The axis is named as
    sac_jax.parallel.SEEDS (not imported: rejax's environment has no sac_jax), for our
    `make_train(config, seed_axis="seeds")`."""
    train = train if seeds == 1 else jax.vmap(train, axis_name="seeds")
    keys = jax.random.key(0) if seeds == 1 else jax.random.split(jax.random.key(0), seeds)
    start = time.perf_counter()
    compiled = jax.jit(train).lower(keys).compile()
    compile_s = time.perf_counter() - start
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        output = jax.block_until_ready(compiled(keys))
        times.append(time.perf_counter() - start)
    return compile_s, times, output


def measure(algo, seeds: int, repeats: int) -> dict:
    before = time.perf_counter() - STARTED
    compile_s, times, (_, (_, returns)) = timed(algo.train, seeds, repeats)
    per_seed = returns.reshape(seeds, -1, returns.shape[-1]).mean(-1)  # (seeds, points)
    curve = per_seed.mean(0)
    return dict(seeds=seeds, to_result_s=round(before + compile_s + times[0], 3),
                compile_s=round(compile_s, 3),
                run_s=round(statistics.median(times), 3), run_times_s=[round(t, 3) for t in times],
                eval_steps=[i * algo.eval_freq for i in range(curve.size)],
                mean_return=[round(float(r), 1) for r in curve],
                final_return_per_seed=[round(float(r), 1) for r in per_seed[:, -1]])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--eval-freq", type=int, default=500)
    parser.add_argument("--cache-dir", default=None,
                        help="JAX's persistent compilation cache here (default: none)")
    args = parser.parse_args()
    if args.cache_dir is not None:  # sac_jax.compilation_cache's settings
        jax.config.update("jax_compilation_cache_dir", args.cache_dir)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
        jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)
    import rejax

    algo = rejax.SAC.create(**CONFIG, eval_freq=args.eval_freq)
    runs = [measure(algo, n, args.repeats) for n in args.seeds]
    for run in runs[1:]:  # started after the first count's runs: not one user's wait
        del run["to_result_s"]
    print(json.dumps(dict(rejax=importlib.metadata.version("rejax"),
                          gymnax=importlib.metadata.version("gymnax"),
                          ml_dtypes=importlib.metadata.version("ml_dtypes"),
                          jax=jax.__version__, device=jax.devices()[0].device_kind,
                          config=CONFIG, eval_freq=args.eval_freq,
                          cache=args.cache_dir is not None, runs=runs)))


if __name__ == "__main__":
    main()
