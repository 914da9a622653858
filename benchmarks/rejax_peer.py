"""rejax, the closest JAX peer, against sac-jax on rejax's own tuned SAC for Pendulum-v1, in one job.

rejax (benchmarks/rejax_side.py, run with `--rejax-python`, the interpreter of a virtual
environment holding rejax 0.1.3 and gymnax 0.0.9): its configuration, `jax.jit(train)`.
Ours, with the same numbers (issue 28's command):

    --preset fast --env Pendulum-v1 --num-envs 1 --updates-per-step 1 --total-steps 10000
    --learning-starts 256 --buffer-size 10000 --eval-every 500 --actor-lr 0.01
    --critic-lr 0.01 --alpha-lr 0.01 --tau 0.02 (and no early stop)

measured two ways for each `--seeds` count:
* program: `jax.jit(make_train(config))` (vmapped over seeds), compile time and the median run
  time of `--repeats` calls, as rejax's; and the share of that run its 20 evaluation points
  take: 20 times the median of `--repeats` timings of one point through the script's own
  compiled `evaluate` (`sac_jax.run.compiled_program`), alone, on the state at the first point.
  (Earlier this was the difference from the same program evaluating at its end only; on a CPU
  whose runs spread by ±15 % that difference of two single runs gave 5-20 % from run to run,
  while one point of 25 episodes takes milliseconds.)
* script: `python scripts/train.py ... --seeds N` in a subprocess with a fresh compilation cache
  (cold) and again with it filled (warm): process wall time, and the summary's `run_s` (training
  after compilation), the time that issue 28 puts against the program's run time (with
  `--rounds R`, the median of the R warm runs', as the program's is of `--repeats` calls; before
  2026-12-07, the first warm run's alone), and `host_s`, the part of it the host spent between
  chunks. On a CPU the script splits the seeds over as many devices, up to one per core, as
  divide their number (`seed_devices`, recorded); the program runs on this process's one
  device, as rejax does.

End to end, each side is timed from its process's start to its trained result (writing results
and exiting excluded on both): rejax's `to_result_s` (rejax_side.py, one process per seed count:
imports, JAX's start, compile, the first call) against our summary's startup + compile + run,
cold and warm. rejax keeps no compiled program between processes by default; it is timed so
(`rejax`) and with JAX's persistent compilation cache on and warm (`rejax_warm`, a cache that
a first rejax process of the count filled), as sac-jax's scripts run by default. With
`--rounds R` each seed count adds R - 1 rounds of a fresh rejax process, a warm one and our warm
script, alternated, and the warm ratios are of the medians of R (`to_result_rounds`): one of
each spread by 10 % or more on a shared CPU.

Each side runs under its own XLA flags and runtime: ours those our scripts set (in the program's
process too, `benchmarks/__init__.py`: on a CPU, the scheduler flag and the one-seed runtime of
one device of one thread), rejax's without them, as its users run it.

What differs between the two trainers (and is not matched): rejax uses swish activations,
observation normalisation and 128 evaluation episodes per point; ours ReLU, raw observations and
5 evaluation episodes plus 20 confirmation episodes for a candidate actor. Returns: rejax's last
evaluation (mean over its seeds), ours the delivered actor's confirmed return (mean over seeds).

    python -m benchmarks.rejax_peer --rejax-python /work/rejax-venv/bin/python --seeds 1 16 \
        --rounds 3

Writes benchmarks/results/rejax_peer-KIND.json (`--name` to choose; command, machine, versions,
date).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import tempfile
import time
from typing import Optional

import jax
import numpy as np

from benchmarks import PEER_ENVIRON
from benchmarks.delivered import train
from benchmarks.provenance import provenance, result_name, write_result
from benchmarks.rejax_side import timed
from sac_jax.parallel import seed_axis
from sac_jax.presets import PRESETS
from sac_jax.run import Chunk, compiled_program, start_args
from sac_jax.train import make_train, make_train_parts

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FLAGS = ["--preset", "fast", "--env", "Pendulum-v1", "--num-envs", "1", "--updates-per-step", "1",
         "--total-steps", "10000", "--learning-starts", "256", "--buffer-size", "10000",
         "--eval-every", "500", "--actor-lr", "0.01", "--critic-lr", "0.01", "--alpha-lr", "0.01",
         "--tau", "0.02", "--no-stop-when-solved"]
CONFIG = PRESETS["fast"].replace(
    env="Pendulum-v1", num_envs=1, updates_per_step=1, total_steps=10_000, learning_starts=256,
    buffer_size=10_000, eval_every=500, actor_lr=0.01, critic_lr=0.01, alpha_lr=0.01, tau=0.02,
    stop_when_solved=False)


def program(seeds: int, repeats: int) -> dict:
    train = make_train(CONFIG, seed_axis=seed_axis(seeds))  # as sac_jax.run's
    compile_s, times, (_, outputs) = timed(train, seeds, repeats)
    delivered = np.asarray(outputs["delivered_return"]).reshape(seeds, -1)
    return dict(compile_s=round(compile_s, 3), run_s=round(statistics.median(times), 3),
                run_times_s=[round(t, 3) for t in times],
                eval_steps=[int(s) for s in np.asarray(outputs["env_steps"]).reshape(seeds, -1)[0]],
                delivered_mean=[round(float(r), 1) for r in delivered.mean(0)],
                final_per_seed=[round(float(r), 1) for r in delivered[:, -1]])


def evaluation_s(seeds: int, repeats: int) -> float:
    """Median seconds of one evaluation point of `seeds` seeds through the script's compiled
    `evaluate`, timed alone on the state at the first point (a fresh copy each call: the
    program consumes its argument)."""
    _, init, chunk, _ = compiled_program(CONFIG, seeds)
    runner = init(*start_args(0, seeds))
    while int(runner.iteration) < CONFIG.prefill_iterations + CONFIG.iterations_per_eval:
        runner = chunk.advance(runner)
    state, times = Chunk.evaluated(runner), []
    for _ in range(repeats):
        copy = jax.block_until_ready(jax.tree_util.tree_map(lambda x: x.copy(), state))
        start = time.perf_counter()
        jax.block_until_ready(chunk.evaluate(copy))
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def script(seeds: int, cache_dir: str) -> dict:
    with tempfile.TemporaryDirectory() as out:
        summary = train(os.path.join(out, "run"), *FLAGS, "--seeds", str(seeds),
                        cache_dir=cache_dir)
    return dict(wall_s=summary["process_wall_s"], compile_s=summary["compile_s"],
                run_s=summary["run_s"], host_s=summary["host_s"],
                startup_s=summary["startup_s"],
                to_result_s=round(summary["startup_s"] + summary["compile_s"]
                                  + summary["run_s"], 3),
                delivered_mean=round(float(np.mean(summary["delivered_return"])), 1),
                seed_devices=summary["seed_devices"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rejax-python", required=True,
                        help="python of a virtual environment with rejax 0.1.3, gymnax 0.0.9")
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 16])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=1,
                        help="alternated end-to-end rounds (a rejax process, our warm script) "
                             "per seed count; the warm ratio is of their medians")
    parser.add_argument("--name", default=None,
                        help="results file name (default rejax_peer-KIND: rejax_peer-cpu)")
    args = parser.parse_args()
    if args.rounds < 1:
        parser.error(f"--rounds must be at least 1, got {args.rounds}")
    source = provenance()

    # rejax as its users run it: without what our scripts (and this process) add to XLA_FLAGS
    # and the environment (benchmarks/__init__.py)
    rejax_env = PEER_ENVIRON

    def rejax_side(n: int, repeats: int, cache: Optional[str] = None) -> dict:
        """One rejax process (its to_result_s is a fresh one's), JAX's cache in `cache`."""
        proc = subprocess.run([args.rejax_python,
                               os.path.join(ROOT, "benchmarks", "rejax_side.py"),
                               "--seeds", str(n), "--repeats", str(repeats)]
                              + ([] if cache is None else ["--cache-dir", cache]),
                              capture_output=True, text=True, env=rejax_env)
        if proc.returncode != 0:
            raise SystemExit(f"rejax side failed: {proc.stderr.strip()[-500:]}")
        lines = proc.stdout.strip().splitlines()
        if not lines:
            raise SystemExit(f"rejax side printed nothing: {proc.stderr.strip()[-500:]}")
        return json.loads(lines[-1])

    rejax = None
    for n in args.seeds:
        side = rejax_side(n, args.repeats)
        rejax = side if rejax is None else dict(rejax, runs=rejax["runs"] + side["runs"])
    rows = []
    for run in rejax["runs"]:
        n = run["seeds"]
        ours = program(n, args.repeats)
        points = len(ours["eval_steps"])
        point_s = evaluation_s(n, max(args.repeats, 5))
        evaluation_share = points * point_s / ours["run_s"]
        with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as theirs:
            cold, warm = script(n, cache), script(n, cache)
            rejax_side(n, 1, theirs)  # fills rejax's cache
            warm_side = lambda: rejax_side(n, 1, theirs)["runs"][0]["to_result_s"]
            rounds = dict(rejax=[run["to_result_s"]], rejax_warm=[warm_side()],
                          ours_warm=[warm["to_result_s"]], ours_warm_run=[warm["run_s"]])
            for _ in range(args.rounds - 1):  # alternated: a drifting machine slows all alike
                rounds["rejax"].append(rejax_side(n, 1)["runs"][0]["to_result_s"])
                rounds["rejax_warm"].append(warm_side())
                again = script(n, cache)
                rounds["ours_warm"].append(again["to_result_s"])
                rounds["ours_warm_run"].append(again["run_s"])
        rejax_s, rejax_warm_s, warm_s, warm_run_s = (
            statistics.median(rounds[k])
            for k in ("rejax", "rejax_warm", "ours_warm", "ours_warm_run"))
        row = dict(seeds=n, rejax=run, program=ours, script_cold=cold, script_warm=warm,
                   to_result_rounds=rounds,
                   evaluation_share=round(evaluation_share, 3),
                   evaluation_point_s=round(point_s, 5),
                   script_over_program=round(warm_run_s / ours["run_s"], 3),
                   rejax_over_program=round(run["run_s"] / ours["run_s"], 3),
                   rejax_over_script_to_result_cold=round(
                       run["to_result_s"] / cold["to_result_s"], 3),
                   rejax_over_script_to_result_warm=round(rejax_s / warm_s, 3),
                   rejax_warm_over_script_to_result_warm=round(rejax_warm_s / warm_s, 3))
        rows.append(row)
        print(f"{n} seed(s): rejax {run['compile_s']:.1f} s compile + {run['run_s']:.2f} s run, "
              f"final {statistics.mean(run['final_return_per_seed']):.1f}; program "
              f"{ours['compile_s']:.1f} + {ours['run_s']:.2f} s, delivered "
              f"{statistics.mean(ours['final_per_seed']):.1f}; script run {warm_run_s:.2f} s "
              f"(wall {cold['wall_s']:.1f} s cold, {warm['wall_s']:.1f} s warm); script/program "
              f"{row['script_over_program']}; evaluation {100 * evaluation_share:.1f} % of the "
              f"program; to the result: rejax {rejax_s:.1f} s ({rejax_warm_s:.1f} s with its cache "
              f"warm), ours {cold['to_result_s']:.1f} s cold, {warm_s:.1f} s warm (medians of "
              f"{args.rounds} round(s) but cold)",
              flush=True)
    parts = make_train_parts(CONFIG)  # the script dispatches num_chunks programs
    write_result(args.name or result_name("rejax_peer"), dict(
        rejax_side=rejax, rows=rows, our_flags=FLAGS, num_iterations=parts.num_iterations,
        num_chunks=parts.num_chunks), source)


if __name__ == "__main__":
    main()
