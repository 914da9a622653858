"""Peak memory of runs against the data they hold and against `sac_jax.memory`'s model.

    python -m benchmarks.memory                                    # CPU, the default sizes
    python -m benchmarks.memory --buffers 20480 4000000 --seeds 1 8

Each run is the README's command (`fast`) with `--buffer-size B` or `--seeds S`, in its own
process; its `summary.json` holds the peak (`peak_host_bytes`: the process's peak RSS; on a GPU
also `peak_device_bytes`) and the model's peak (`memory_model_peak_bytes`). From pairs of runs:
bytes per replay slot = the peak's growth between the two buffer sizes over the slots added,
against a slot's own data bytes; bytes per seed = the growth between the two seed counts (their
buffers included). Writes benchmarks/results/memory.json (command, machine, versions, date).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

import sac_jax
from benchmarks.provenance import provenance, write_result
from sac_jax import memory

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def peak(out: str, *flags: str) -> dict:
    """Runs scripts/train.py into `out` with `flags`; its summary's memory figures."""
    argv = [sys.executable, os.path.join(ROOT, "scripts", "train.py"), "--out", out, *flags]
    proc = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True)
    if proc.returncode:
        raise SystemExit(f"{' '.join(argv)} failed:\n{proc.stderr[-2000:]}")
    with open(os.path.join(out, "summary.json")) as f:
        summary = json.load(f)
    return {key: summary[key] for key in ("peak_host_bytes", "peak_device_bytes",
                                          "memory_model_peak_bytes", "total_steps")}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--buffers", type=int, nargs=2, default=[4_000_000, 8_000_000])
    parser.add_argument("--seeds", type=int, nargs=2, default=[2, 8],
                        help="two seed counts above 1 (one seed runs an unbatched program)")
    args = parser.parse_args()
    root = tempfile.mkdtemp(prefix="memory-")
    config = sac_jax.PRESETS["fast"]
    slot = memory.need(config, 1).replay // config.buffer_size  # one slot's data bytes
    peak(os.path.join(root, "warmup"))  # the compilation cache holds the program from here on
    buffers = {b: peak(os.path.join(root, f"buffer{b}"), "--buffer-size", str(b))
               for b in args.buffers}
    seeds = {s: peak(os.path.join(root, f"seeds{s}"), "--seeds", str(s)) for s in args.seeds}
    (b0, r0), (b1, r1) = sorted(buffers.items())
    (s0, q0), (s1, q1) = sorted(seeds.items())
    key = "peak_host_bytes"
    result = {
        "slot_data_bytes": slot,
        "bytes_per_slot": round((r1[key] - r0[key]) / (b1 - b0), 2),
        "bytes_per_seed": round((q1[key] - q0[key]) / (s1 - s0)),
        "seed_data_bytes": memory.need(config, 1).replay + memory.need(config, 1).state,
        "buffers": buffers, "seeds": seeds}
    result["per_slot_over_data"] = round(result["bytes_per_slot"] / slot, 3)
    print(json.dumps({k: v for k, v in result.items() if k not in ("buffers", "seeds")}))
    write_result("memory", result, provenance())


if __name__ == "__main__":
    main()
