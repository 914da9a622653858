"""Training seconds until the seeds of a finished run have solved its task, from its directory.

    python benchmarks/solve_times.py RUN_DIR [RUN_DIR ...]

A seed has solved at its first evaluation whose return reaches the task's threshold
(`summary.json`'s `solved_at_step`). For each run: the training seconds (`metrics.csv`'s
`wall_s`, compile excluded) at which half of the seeds and all of them had solved, and at which
the mean over seeds first reached the threshold (`solved_wall_s`), with compile and run times,
and the training seconds of each evaluation period (`period_s`: the first covers the prefill).
"""

from __future__ import annotations

import csv
import json
import os
import sys

import numpy as np


def solve_times(run_dir: str) -> dict:
    with open(os.path.join(run_dir, "summary.json")) as f:
        summary = json.load(f)
    with open(os.path.join(run_dir, "metrics.csv")) as f:
        wall_at = {int(row["env_steps"]): float(row["wall_s"]) for row in csv.DictReader(f)}
    walls = [wall_at[step] for step in sorted(wall_at)]
    solved = [wall_at[step] for step in summary["solved_at_step"] if step is not None]
    seeds = summary["seeds"]

    def when(fraction):
        count = int(np.ceil(fraction * seeds))
        return sorted(solved)[count - 1] if len(solved) >= count else None

    return {"seeds": seeds, "solved": len(solved), "half_solved_s": when(0.5),
            "all_solved_s": when(1.0), "mean_solved_s": summary["solved_wall_s"],
            "compile_s": summary["compile_s"], "run_s": summary["run_s"],
            "period_s": [round(b - a, 2) for a, b in zip([0.0] + walls, walls)]}


if __name__ == "__main__":
    if len(sys.argv) < 2:
        raise SystemExit(__doc__)
    for run_dir in sys.argv[1:]:
        print(json.dumps({"run": run_dir, **solve_times(run_dir)}))
