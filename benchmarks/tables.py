"""BENCHMARKS.md's generated tables, written from benchmarks/results/*.json, so that a figure
and the run that produced it cannot drift apart.

    python -m benchmarks.tables            # rewrites every generated table in BENCHMARKS.md
    python -m benchmarks.tables --check    # exit 1 if BENCHMARKS.md differs from its results

A generated table stands between `<!-- generated: NAME -->` and `<!-- end generated -->` in
BENCHMARKS.md; `TABLES[NAME]` writes it from the results files it names (each row says which
file, and the file holds its command, machine, versions and date).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
from typing import Callable, Dict, List

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, "benchmarks", "results")
DOC = os.path.join(ROOT, "BENCHMARKS.md")
BLOCK = re.compile(r"(<!-- generated: (\S+) -->\n)(.*?)(<!-- end generated -->)", re.S)


def _load(name: str) -> dict:
    with open(os.path.join(RESULTS, f"{name}.json")) as f:
        return json.load(f)


def _date(data: dict) -> str:
    return data["provenance"]["date"][:10]


def _span(values, fmt="{:,.0f}") -> str:
    low, high = min(values), max(values)
    return fmt.format(low) if low == high else f"{fmt.format(low)}-{fmt.format(high)}"


def _scores(values) -> str:
    values = [round(v, 1) for v in values]
    if len(set(values)) > 1:
        return f"{min(values):g} to {max(values):g}"
    return f"{values[0]:g}" + (f" for all {len(values)}" if len(values) > 1 else "")


def _table(header: List[str], rows: List[List[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def delivered_cpu() -> str:
    """The README's command per seed, cold starts and the many-seed run (CPU)."""
    rows = []
    for name in ("delivered", "delivered-cold"):
        data = _load(name)
        result, date = data["result"], _date(data)
        runs = result["runs"]
        if runs:
            rows.append([f"seeds {runs[0]['seed']}-{runs[-1]['seed']}, one run each", date,
                         _span([r["solved_at_step"] for r in runs]),
                         _span([r["solved_wall_s"] for r in runs], "{:.1f}"),
                         f"median {np.median([r['solved_process_s'] for r in runs]):.1f}, max "
                         f"{max(r['solved_process_s'] for r in runs):.1f}",
                         _scores([r["gymnasium_return"] for r in runs]), f"`{name}.json`"])
        if result.get("cold"):
            cold = result["cold"]
            rows.append(["cold cache, seed 0", date, "-", "-",
                         f"{cold['solved_process_s']:.1f} (compile {cold['compile_s']:.1f})",
                         _scores([cold["gymnasium_return"]]), f"`{name}.json`"])
        if result.get("many"):
            many = result["many"]
            rows.append([f"`--seeds {many['seeds']}` in one run", date,
                         f"{many['solved']}/{many['seeds']} solved",
                         f"last {many['all_solved_wall_s']:.1f}",
                         f"last {many['all_solved_process_s']:.1f}",
                         _scores(many["return"]), f"`{name}.json`"])
    return _table(["run", "date", "solved at step", "training s", "from process start s",
                   "Gymnasium return (10 episodes)", "results"], rows)


def delivered_gpu() -> str:
    """Seeds 0-2 alone and 256 seeds in one run (H100), scored in our environment."""
    rows = []
    for name in ("delivered-h100", "delivered-warm-h100"):
        data = _load(name)
        result, date = data["result"], _date(data)
        runs = result["runs"]
        rows.append([f"seeds {', '.join(str(r['seed']) for r in runs)}, one run each", date,
                     ", ".join(f"{r['solved_wall_s']:.1f}" for r in runs),
                     ", ".join(f"{r['solved_process_s']:.1f}" for r in runs),
                     _scores([r["gymnasium_return"] for r in runs]) + " (Gymnasium)",
                     f"`{name}.json`"])
        many = result["many"]
        rows.append([f"{many['seeds']} seeds in one run, cache {many.get('cache', 'cold')}",
                     date, f"all after {many['all_solved_wall_s']:.1f}",
                     f"all after {many['all_solved_process_s']:.1f}",
                     f"{many['at_least_950']}/{many['seeds']} ≥ 950, lowest "
                     f"{min(many['return']):g} (ours)", f"`{name}.json`"])
    return _table(["run", "date", "training s", "from process start s", "return (10 episodes)",
                   "results"], rows)


def presets() -> str:
    """4 seeds of each preset; every delivered policy scored over 10 episodes."""
    rows = []
    for name in ("presets_delivered-h100", "presets_delivered-idp-confirm100-h100"):
        data = _load(name)
        for run, r in data["result"].items():
            label = "`fast` on InvertedDoublePendulum-v5" if run == "idp" else f"`{run}`"
            rows.append([label, f"{r['env']} ({r['threshold']:g}, {r['judged_in']})",
                         r.get("confirm_episodes", 20), f"{r['solved']}/{r['seeds']}",
                         _scores(r["scores"]), _date(data), f"`{name}.json`"])
    return _table(["configuration", "task (solved, judged in)", "confirmation episodes",
                   "delivered ≥ solved", "scores", "date", "results"], rows)


def brax() -> str:
    """Brax's SAC against ours on the same physics (medians over the seeds)."""
    data = _load("brax_peer-h100")
    result, date = data["result"], _date(data)
    rows = []
    for who, label in (("brax", "Brax SAC (first evaluation ≥ 950)"),
                       ("ours", "sac-jax (delivered policy)")):
        m = result["median"][who]
        steps = [r[who]["solved_at_step"] for r in result["runs"]]
        rows.append([label, date, f"{m['compile_s']:.1f}",
                     f"{m['solve_total_s']:.1f} ({m['solve_train_s']:.2f})",
                     _span(steps), f"{m['env_steps_per_s']:,.0f}"])
    ratio = result["ratio_ours_over_brax"]
    rows.append(["ours / Brax", "", f"{ratio['compile_s']:.2f}",
                 f"{ratio['solve_total_s']:.2f} ({ratio['solve_train_s']:.2f})", "",
                 f"{ratio['env_steps_per_s']:.2f}"])
    return _table(["trainer", "date", "compile s", "time to solved s (training only)",
                   "solved at step", "env steps/s"], rows)


def memory() -> str:
    """Peak memory per replay slot and per seed against their data (CPU)."""
    data = _load("memory")
    r, date = data["result"], _date(data)
    return _table(["quantity", "date", "peak bytes", "data bytes", "ratio"], [
        ["per replay slot (`fast`, 1 seed)", date, f"{r['bytes_per_slot']:.1f}",
         r["slot_data_bytes"], f"{r['per_slot_over_data']:.2f}"],
        ["per seed, its buffer included (`fast`)", date, f"{r['bytes_per_seed']:,}",
         f"{r['seed_data_bytes']:,}", f"{r['bytes_per_seed'] / r['seed_data_bytes']:.1f}"]])


TABLES: Dict[str, Callable[[], str]] = {
    "delivered-cpu": delivered_cpu, "delivered-gpu": delivered_gpu, "presets": presets,
    "brax": brax, "memory": memory}


def render(text: str) -> str:
    """`text` (BENCHMARKS.md) with every generated table written anew from the results."""
    def table(match):
        name = match.group(2)
        if name not in TABLES:
            raise SystemExit(f"BENCHMARKS.md: no generated table named {name!r}")
        return match.group(1) + TABLES[name]() + match.group(4)

    return BLOCK.sub(table, text)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true",
                        help="exit 1 if BENCHMARKS.md's generated tables differ from the results")
    args = parser.parse_args()
    with open(DOC) as f:
        text = f.read()
    new = render(text)
    if args.check:
        if new != text:
            print("BENCHMARKS.md differs from benchmarks/results: run python -m benchmarks.tables",
                  file=sys.stderr)
            return 1
        return 0
    with open(DOC, "w") as f:
        f.write(new)
    print(f"wrote {DOC}: {len(BLOCK.findall(new))} generated tables")
    return 0


if __name__ == "__main__":
    sys.exit(main())
