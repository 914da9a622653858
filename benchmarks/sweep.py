"""A hyperparameter sweep in one program against the same runs one by one.

    python -m benchmarks.sweep                          # CPU: 8 settings x 2 seeds vs 16 runs
    python -m benchmarks.sweep --grid 64 --seeds 4 --separate 1   # GPU: 64 x 4 vs one run

The sweep is `python scripts/sweep.py --preset fast --seeds K --set ...` (every setting of the
grid changes numbers only, so all S x K runs are one vmapped program); the separate runs are
`python scripts/train.py --preset fast <the setting's flags> --seed s`, each in its own process,
for the first `--separate` (setting, seed) pairs (default all of them; the first setting is
`fast` itself, so `--separate 1` is one seed of the README's run). Every process is timed
from its start to its exit (compilation included). Both sides start from an empty compilation
cache directory of their own (cold: the separate runs of one setting share its program, as a
user's reruns would); `--warm` then runs each side once more on its cache. The `fast` preset
stops each run once its delivered policy scores 1000 over 2 measurements, within 20,480
steps, so a setting that never solves runs the whole budget. Writes benchmarks/results/sweep-KIND.json
(KIND: cpu, h100, ...; `--name` to choose).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
import time

from benchmarks.provenance import machine_kind, provenance, write_result

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GRIDS = {  # the first setting of each is the `fast` preset itself
    "8": {"actor_lr": [3e-3, 1e-3], "critic_lr": [3e-3, 1e-3], "tau": [0.02, 0.005]},
    "64": {"actor_lr": [3e-3, 1e-3, 3e-4, 1e-2], "critic_lr": [3e-3, 1e-3, 3e-4, 1e-2],
           "tau": [0.02, 0.005], "alpha_lr": [1e-3, 3e-3]},
}


def _process(argv) -> float:
    """Runs `argv` from the repository root; its wall seconds (SystemExit if it fails)."""
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, *argv], cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if proc.returncode:
        raise SystemExit(f"{' '.join(argv)} failed:\n{proc.stderr[-2000:]}")
    print((proc.stdout.strip().splitlines() or [""])[-1], flush=True)
    return wall


def run_sweep(grid: dict, seeds: int, out: str, cache: str) -> dict:
    sets = [f"{name}={','.join(map(repr, values))}" for name, values in grid.items()]
    wall = _process(["scripts/sweep.py", "--preset", "fast", "--seeds", str(seeds),
                     "--out", out, "--cache-dir", cache, *[a for s in sets for a in ("--set", s)]])
    with open(os.path.join(out, "programs", "0", "summary.json")) as f:
        summary = json.load(f)
    with open(os.path.join(out, "results.csv")) as f:
        rows = list(csv.DictReader(f))
    returns = [float(r["delivered_return"]) for r in rows]
    return {"process_wall_s": round(wall, 2), "compile_s": summary["compile_s"],
            "run_s": summary["run_s"], "runs": len(rows),
            "solved": sum(r["solved_at_step"] != "" for r in rows),
            "delivered_return_mean": sum(returns) / len(returns),
            "delivered_return_min": min(returns)}


def run_separate(grid: dict, seeds: int, count: int, root: str, cache: str) -> dict:
    import itertools

    points = [dict(zip(grid, values)) for values in itertools.product(*grid.values())]
    pairs = [(p, s) for p in points for s in range(seeds)][:count]
    walls = []
    for i, (point, seed) in enumerate(pairs):
        flags = [a for k, v in point.items() for a in (f"--{k.replace('_', '-')}", repr(v))]
        walls.append(round(_process(["scripts/train.py", "--preset", "fast", "--seed", str(seed),
                                     "--out", os.path.join(root, f"run{i}"), "--cache-dir",
                                     cache, *flags]), 2))
    return {"runs": len(pairs), "process_wall_s": round(sum(walls), 2), "each_s": walls}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", choices=sorted(GRIDS), default="8",
                        help="settings: 8 (actor_lr, critic_lr, tau) or 64 (and alpha_lr)")
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--separate", type=int, default=None,
                        help="separate runs to time (default: every setting x seed)")
    parser.add_argument("--warm", action="store_true", help="run each side again, warm")
    parser.add_argument("--name", default=None)
    args = parser.parse_args()
    source = provenance()
    grid = GRIDS[args.grid]
    settings = 1
    for values in grid.values():
        settings *= len(values)
    count = settings * args.seeds if args.separate is None else args.separate
    root = tempfile.mkdtemp(prefix="sweep-bench-")
    caches = {side: tempfile.mkdtemp(prefix=f"cache-{side}-", dir=root)
              for side in ("sweep", "separate")}
    result = {"grid": grid, "settings": settings, "seeds": args.seeds}
    for label in ("cold", "warm") if args.warm else ("cold",):
        sweep = run_sweep(grid, args.seeds, os.path.join(root, f"sweep-{label}"),
                          caches["sweep"])
        separate = run_separate(grid, args.seeds, count, os.path.join(root, f"sep-{label}"),
                                caches["separate"])
        result[label] = {"sweep": sweep, "separate": separate,
                         "ratio": round(sweep["process_wall_s"] / separate["process_wall_s"], 3)}
        print(json.dumps(result[label]), flush=True)
    write_result(args.name or f"sweep-{machine_kind()}", result, source)


if __name__ == "__main__":
    main()
