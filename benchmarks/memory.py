"""Peak memory of runs against the data they hold and against `sac_jax.memory`'s estimate.

    python -m benchmarks.memory                                    # CPU, the default sizes
    python -m benchmarks.memory --buffers 10000 4000000 8000000 --seeds 1 8

Each run is the README's command (`fast`) with `--buffer-size B` (1 seed) or `--seeds S` (with
the smallest buffer), in its own process; its `summary.json` holds the peak
(`peak_host_bytes`: the process's peak RSS; on a GPU also `peak_device_bytes`) and the model's
estimate of it (`memory_model_peak_bytes`, its parts in `memory_model`). From the two largest
of each: bytes per replay slot = the peak's growth over the slots added, against a slot's own
data bytes; bytes per seed = the growth over the seeds added (their buffers included); and for
every run the estimate over the measured peak. Writes benchmarks/results/memory.json (command,
machine, versions, date; memory-KIND.json on an accelerator, where the peak is the device's,
`peak_bytes_in_use`). `--largest SLOTS` adds a run of the most seeds of SLOTS slots each that
fit (run with XLA_PYTHON_CLIENT_PREALLOCATE=false on a GPU, so that this process, which reads
the free memory, leaves it to the runs).

The runs themselves allocate as a user's run does, with JAX's default preallocation (the
variable is removed from their environment): without it, XLA's BFC allocator grows region by
region and hands out a whole region's chunk where splitting it would leave less than 128 MB,
which counted as in use. An H200 measured 659 MB at peak for 10^7 slots of 44 bytes that way
(1.54x the data), against 47.7 MB for 10^6 slots.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile

import jax

import sac_jax
from benchmarks.delivered import TrainFailed, train
from benchmarks.provenance import provenance, result_name, write_result
from sac_jax import memory

ACCELERATOR = jax.default_backend() != "cpu"


def peak(out: str, *flags: str, may_fail: bool = False) -> dict:
    """Runs scripts/train.py into `out` with `flags`; its summary's memory figures (where it
    `may_fail`, {"failed": its last line on stderr} if it does).

    On an accelerator it runs twice and keeps the second run, whose program comes from the
    compilation cache: a cold run's `peak_bytes_in_use` also counts XLA's autotuning buffers,
    allocated while compiling (kept as `cold_peak_device_bytes`)."""
    if ACCELERATOR and not may_fail:
        cold = _peak(out + "-cold", *flags)
        return dict(_peak(out, *flags), cold_peak_device_bytes=cold["peak_device_bytes"])
    return _peak(out, *flags, may_fail=may_fail)


def _peak(out: str, *flags: str, may_fail: bool = False) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "XLA_PYTHON_CLIENT_PREALLOCATE"}
    try:
        summary = train(out, *flags, env=env)
    except TrainFailed as failed:
        if not may_fail:
            raise
        return {"failed": (failed.stderr.strip().splitlines() or [""])[-1][:500]}
    return {key: summary[key] for key in ("peak_host_bytes", "peak_device_bytes",
                                          "memory_model_peak_bytes", "memory_model",
                                          "total_steps")}


LARGEST_SHARE = 0.9
"""The share of the free memory `largest` fills: on an H100, 1,411 seeds of 10^6 slots, which
the estimate fitted in all of it, ran out of device memory in `init` (the allocator's
fragmentation and `init`'s own temporaries are not in the estimate)."""


def largest(config, slots: int, temporaries_per_seed: float) -> int:
    """The most seeds of `config` with `slots` replay slots each whose estimate fits in the
    memory available now: the data and a checkpoint's copy where it fits (`memory.check`'s
    rule, which runs before compiling), and the chunk's temporaries per seed, measured by the
    runs before (the process's own memory is outside what is available)."""
    free, where = memory.available()
    free = int(free * LARGEST_SHARE)
    config = config.replace(buffer_size=slots)
    per_seed = memory.need(config, 1, where).replay + memory.need(config, 1, where).state
    low, high = 1, max(1, free // per_seed)
    while low < high:  # bisection: the need grows with the seeds
        mid = (low + high + 1) // 2
        if memory.need(config, mid, where, available=free).peak + mid * temporaries_per_seed <= free:
            low = mid
        else:
            high = mid - 1
    return low


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--buffers", type=int, nargs="+",
                        default=[10_000, 100_000, 1_000_000, 10_000_000],
                        help="buffer sizes run with 1 seed (the two largest give bytes per slot)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 16, 64],
                        help="seed counts run with the smallest buffer (the two largest give "
                             "bytes per seed)")
    parser.add_argument("--largest", type=int, default=0, metavar="SLOTS",
                        help="also run the most seeds of SLOTS replay slots each that the memory "
                             "check accepts here (0: not)")
    parser.add_argument("--largest-steps", type=int, default=2048,
                        help="--total-steps of that run (its memory is allocated at the start)")
    args = parser.parse_args()
    root = tempfile.mkdtemp(prefix="memory-")
    config = sac_jax.PRESETS["fast"]
    slot = memory.need(config, 1).replay // config.buffer_size  # one slot's data bytes
    small = min(args.buffers)
    # the compilation cache holds the smallest buffer's program from here on
    _peak(os.path.join(root, "warmup"), "--buffer-size", str(small))
    buffers = {b: peak(os.path.join(root, f"buffer{b}"), "--buffer-size", str(b))
               for b in sorted(args.buffers)}
    seeds = {s: peak(os.path.join(root, f"seeds{s}"), "--seeds", str(s), "--buffer-size",
                     str(small)) for s in sorted(args.seeds)}
    (b0, r0), (b1, r1) = list(buffers.items())[-2:]
    (s0, q0), (s1, q1) = list(seeds.items())[-2:]
    on_device = r0["peak_device_bytes"] is not None  # an accelerator: its memory, not the host's
    key = "peak_device_bytes" if on_device else "peak_host_bytes"
    one_seed = memory.need(config.replace(buffer_size=small), 1)
    result = {
        "measured": key,
        "slot_data_bytes": slot,
        "bytes_per_slot": round((r1[key] - r0[key]) / (b1 - b0), 2),
        "bytes_per_seed": round((q1[key] - q0[key]) / (s1 - s0)),
        "seed_data_bytes": one_seed.replay + one_seed.state,
        "seed_buffer_size": small,
        "buffers": buffers, "seeds": seeds,
        "estimate_over_peak": {f"{grid}: {s} seed(s), {b:,} slots": round(
            r["memory_model_peak_bytes"] / r[key], 3)  # the grids share 1 seed, `small` slots
            for (grid, s, b, r) in [("buffers", 1, b, r) for b, r in buffers.items()]
            + [("seeds", s, small, r) for s, r in seeds.items()]}}
    result["per_slot_over_data"] = round(result["bytes_per_slot"] / slot, 3)
    if args.largest:
        temporaries = q1["memory_model"]["temporaries"] / s1
        n = largest(config, args.largest, temporaries)
        free, where = memory.available()
        run = peak(os.path.join(root, "largest"), "--seeds", str(n), "--buffer-size",
                   str(args.largest), "--total-steps", str(args.largest_steps), may_fail=True)
        result["largest"] = dict(run, seeds=n, buffer_size=args.largest, available_bytes=free,
                                 total_steps_asked=args.largest_steps)
    print(json.dumps({k: v for k, v in result.items() if k not in ("buffers", "seeds")}))
    write_result("memory" if not on_device else result_name("memory"), result, provenance())


if __name__ == "__main__":
    main()
