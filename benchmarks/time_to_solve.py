"""Wall-clock time to solve with the README's default command, cold and warm.

Runs `python scripts/train.py [ARGS] --out DIR` twice in fresh processes sharing one new, empty
JAX compilation-cache directory: the first run compiles (cold), the second loads the compiled
program from the cache (warm). Time to solve = process start to the first evaluation point
whose mean return over seeds reaches the task's threshold (950 on InvertedPendulum):
total process wall time minus the training time after that point.

    python benchmarks/time_to_solve.py                 # the default preset and seeds
    python benchmarks/time_to_solve.py --preset cleanrl --seeds 1
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def timed_run(args, cache_dir, out_dir):
    start = time.perf_counter()
    subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "train.py"), *args,
                    "--cache-dir", cache_dir, "--out", out_dir], check=True,
                   stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    with open(os.path.join(out_dir, "summary.json")) as f:
        summary = json.load(f)
    solved = summary["solved_wall_s"]
    to_solve = None if solved is None else wall - (summary["run_s"] - solved)
    return wall, summary, to_solve


def main():
    args = sys.argv[1:]
    with tempfile.TemporaryDirectory() as tmp:
        cache = os.path.join(tmp, "cache")
        print("| run | process wall s | compile s | train s | time to solve s | solved at step |")
        print("| --- | ---: | ---: | ---: | ---: | --- |")
        for name in ("cold", "warm"):
            wall, s, to_solve = timed_run(args, cache, os.path.join(tmp, name))
            solve = "not solved" if to_solve is None else f"{to_solve:.1f}"
            print(f"| {name} | {wall:.1f} | {s['compile_s']:.1f} | {s['run_s']:.1f} | {solve} | "
                  f"{s['solved_at_step']} |", flush=True)


if __name__ == "__main__":
    main()
