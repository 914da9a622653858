"""Wall-clock time to solve with the README's default command, cold and warm.

Runs `python scripts/train.py [ARGS] --out DIR` twice in fresh processes sharing one new, empty
JAX compilation-cache directory: the first run compiles (cold), the second loads the compiled
program from the cache (warm). Time to solve = process start to the moment the script prints
the first evaluation line whose return (mean over seeds) reaches the task's threshold (950 on
InvertedPendulum), read from its output as it comes; with several seeds also the moment its
line first counts half of the seeds solved ("solved K/N", each seed's first evaluation at the
threshold), and the training seconds (compile excluded) at which half had solved, from the run's
`metrics.csv` (`benchmarks/solve_times.py`). With one seed the two times are the same.

    python benchmarks/time_to_solve.py                 # the default preset and seeds
    python benchmarks/time_to_solve.py --preset cleanrl --seeds 1
    python benchmarks/time_to_solve.py --seeds 256 --hidden-dtype bfloat16   # on a GPU
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from benchmarks.solve_times import solve_times  # noqa: E402
from envs import SOLVED_RETURN  # noqa: E402


def timed_run(args, cache_dir, out_dir):
    """(process wall s, summary, seconds from process start to the progress line where the mean
    over seeds first reaches the threshold, and to the one where half the seeds have solved)."""
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, os.path.join(ROOT, "scripts", "train.py"), *args,
                             "--cache-dir", cache_dir, "--out", out_dir],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    threshold, to_solve, to_half = None, None, None
    for line in proc.stdout:
        header = re.search(r" on (\S+): ", line)
        if threshold is None and header:
            threshold = SOLVED_RETURN.get(header.group(1))
        point = re.match(r"step\s+\d+ \| eval\s+(\S+)", line)
        if not point or threshold is None:
            continue
        mean_solved = point.group(1) != "-" and float(point.group(1)) >= threshold
        count = re.search(r"\| solved (\d+)/(\d+)$", line.rstrip())
        half_solved = (2 * int(count.group(1)) >= int(count.group(2))) if count else mean_solved
        if to_solve is None and mean_solved:
            to_solve = time.perf_counter() - start
        if to_half is None and half_solved:
            to_half = time.perf_counter() - start
    if proc.wait() != 0:
        raise SystemExit(f"train.py exited with {proc.returncode}")
    wall = time.perf_counter() - start
    with open(os.path.join(out_dir, "summary.json")) as f:
        summary = json.load(f)
    return wall, summary, to_solve, to_half


def _seconds(value, digits: int = 1) -> str:
    return "not solved" if value is None else f"{value:.{digits}f}"


def main():
    args = sys.argv[1:]
    with tempfile.TemporaryDirectory() as tmp:
        cache = os.path.join(tmp, "cache")
        print("| run | process wall s | compile s | train s | time to solve s (mean over seeds) "
              "| half of the seeds solved s | of it training s | seeds solved |")
        print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
        for name in ("cold", "warm"):
            out = os.path.join(tmp, name)
            wall, s, to_solve, to_half = timed_run(args, cache, out)
            times = solve_times(out)
            print(f"| {name} | {wall:.1f} | {s['compile_s']:.1f} | {s['run_s']:.1f} | "
                  f"{_seconds(to_solve)} | {_seconds(to_half)} | "
                  f"{_seconds(times['half_solved_s'], 2)} | {times['solved']}/{s['seeds']} |",
                  flush=True)


if __name__ == "__main__":
    main()
