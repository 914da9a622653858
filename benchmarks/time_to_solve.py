"""Wall-clock time to solve with the README's default command, cold and warm.

Runs `python scripts/train.py [ARGS] --out DIR` twice in fresh processes sharing one new, empty
JAX compilation-cache directory: the first run compiles (cold), the second loads the compiled
program from the cache (warm). Time to solve = process start to the moment the script prints
the first evaluation line whose return (mean over seeds) reaches the task's threshold (950 on
InvertedPendulum), read from its output as it comes.

    python benchmarks/time_to_solve.py                 # the default preset and seeds
    python benchmarks/time_to_solve.py --preset cleanrl --seeds 1
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

from sac_jax.presets import SOLVED_RETURN  # noqa: E402


def timed_run(args, cache_dir, out_dir):
    """(process wall s, summary, seconds from process start to the solving progress line)."""
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, os.path.join(ROOT, "scripts", "train.py"), *args,
                             "--cache-dir", cache_dir, "--out", out_dir],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    threshold, to_solve = None, None
    for line in proc.stdout:
        header = re.search(r" on (\S+): ", line)
        if threshold is None and header:
            threshold = SOLVED_RETURN.get(header.group(1))
        point = re.match(r"step\s+\d+ \| eval\s+(\S+)", line)
        if to_solve is None and point and threshold is not None and \
                point.group(1) != "-" and float(point.group(1)) >= threshold:
            to_solve = time.perf_counter() - start
    if proc.wait() != 0:
        raise SystemExit(f"train.py exited with {proc.returncode}")
    wall = time.perf_counter() - start
    with open(os.path.join(out_dir, "summary.json")) as f:
        summary = json.load(f)
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
