"""What XLA's options cost and save on a first run: for each `--variant` (an XLA_FLAGS string),
the README's command (`python scripts/train.py`, the `fast` preset) from an empty compilation
cache and then again from the cache it filled, each in its own process.

    python -m benchmarks.compile_options --variant "" --variant "--xla_gpu_autotune_level=0"

Per variant and run (cold, warm), from summary.json: seconds from process start to the run's
start (`startup_s`), building the programs (`compile_s`, a cache read when warm), training to
the solved delivered policy (`solved_wall_s`) and from process start (`solved_process_s`), the
whole process (`process_wall_s`) and the delivered return. An option that compiles faster but
trains slower shows in the warm run. Writes benchmarks/results/compile_options-KIND.json.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile

from benchmarks.delivered import train
from benchmarks.provenance import provenance, result_name, write_result

FIELDS = ("startup_s", "compile_s", "run_s")


def measure(flags: str, root: str, extra: list) -> dict:
    """One variant: a cold run, then a warm one from the cache the cold run filled."""
    env = dict(os.environ, XLA_FLAGS=" ".join(filter(None, [os.environ.get("XLA_FLAGS"),
                                                             flags])))
    root = tempfile.mkdtemp(dir=root)
    row = {"xla_flags": flags}
    for run in ("cold", "warm"):
        try:
            s = train(os.path.join(root, run), *extra, cache_dir=os.path.join(root, "cache"),
                      env=env)
        except SystemExit as failed:  # e.g. a flag this XLA does not know: the others go on
            row["error"] = str(failed)[-500:]
            break
        row[run] = {**{k: s[k] for k in FIELDS}, "solved_wall_s": s["solved_wall_s"][0],
                    "solved_process_s": s["solved_process_s"][0],
                    "process_wall_s": s["process_wall_s"],
                    "delivered_return": s["delivered_return"][0]}
    print(json.dumps(row), flush=True)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", action="append", required=True,
                        help="XLA_FLAGS to add (\"\" for XLA's defaults); repeat to compare")
    parser.add_argument("--train-flag", action="append", default=[],
                        help="a flag for scripts/train.py, e.g. --train-flag=--seed=3")
    args = parser.parse_args()
    root = tempfile.mkdtemp(prefix="compile-options-")
    rows = [measure(v, root, args.train_flag) for v in args.variant]
    write_result(result_name("compile_options"), {"variants": rows}, provenance())


if __name__ == "__main__":
    main()
