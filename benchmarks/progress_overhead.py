"""Cost of following a run from the host: progress lines, TensorBoard, checkpoints, finiteness
checks.

In one process, the same configuration and seeds run three ways, interleaved, `--repeats`
times each (compile time excluded from all):
    single scan   the pure `make_train` program: one `lax.scan`, nothing reported until it ends
    chunks        `sac_jax.run.run_training` driven chunk by chunk with nothing attached
    followed      the same, writing TensorBoard scalars at every evaluation point and a
                  checkpoint (the whole state, replay buffers included, written on a
                  background thread) after it, as `scripts/train.py` does (which also
                  prints one line per point); its time runs until the last of those writes
                  ends (before 2026-11-30 it stopped short of the final checkpoint's). The
                  scalars are written by a child process (`sac_jax.records_process`), as the
                  script's are since 2026-12-08 (before, on a thread of this process)
Each figure is the median over the repeats; the overheads are medians of the ratios of runs
made back to back (the machine's speed drifts between repeats). `followed_host_pct` is the
direct measure: the share of the followed run's time that the host spends between chunks
(finiteness check, progress, TensorBoard, checkpoint) while the device waits for the next
chunk (`summary["host_s"]` of `run_training`), and waiting for the last writes at the end.
On a CPU the figures of whole runs scatter by about 10% run to run, and the single scan and
the chunked runs take different numerical paths (float rounding of two programs), so their
evaluations can last different numbers of steps.

    python -m benchmarks.progress_overhead                  # the default preset, 1 seed
    python -m benchmarks.progress_overhead --preset pendulum --seeds 4 --repeats 5
    python -m benchmarks.progress_overhead --seeds 256 --repeats 5 --no-single-scan  # GPU
    python -m benchmarks.progress_overhead --preset rejax   # rejax's Pendulum-v1 configuration

Printed as one JSON line and written to benchmarks/results/NAME.json (`--name`, default
progress_overhead-PRESET-KIND: progress_overhead-fast-cpu; command, machine, versions, date).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time


import jax
import numpy as np

import sac_jax
from benchmarks.configurations import NAMES, configuration
from benchmarks.provenance import provenance, result_name, write_result
from sac_jax import run_checkpoint, run_dir
from sac_jax.records_process import RecordsProcess
from sac_jax.run import run_training


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default=sac_jax.DEFAULT_PRESET, choices=NAMES,
                        help="a preset, or rejax for rejax's Pendulum-v1 configuration")
    parser.add_argument("--seeds", type=int, default=1)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--no-single-scan", action="store_true",
                        help="only the chunked runs, bare and followed (more repeats in the time)")
    parser.add_argument("--name", default=None, help="results file benchmarks/results/NAME.json "
                        "(default progress_overhead-PRESET-KIND)")
    args = parser.parse_args()
    source = provenance()
    sac_jax.enable_compilation_cache()
    config = configuration(args.preset)
    keys = jax.random.split(jax.random.key(0), args.seeds)
    if not args.no_single_scan:
        train = sac_jax.make_train(config, seed_axis="seeds")  # resets as the chunked run's
        whole = jax.jit(jax.vmap(train, axis_name="seeds")).lower(keys).compile()
        jax.block_until_ready(whole(keys))  # warm-up
    run_training(config, seeds=args.seeds)  # compiles and warms up the chunk
    times = {"chunks": [], "followed": []}
    if not args.no_single_scan:
        times["single_scan"] = []
    returns, host = {}, []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.repeats):
            if not args.no_single_scan:
                start = time.perf_counter()
                _, metrics = jax.block_until_ready(whole(keys))
                times["single_scan"].append(time.perf_counter() - start)
                returns["single_scan"] = np.asarray(metrics["eval_return"])
            result = run_training(config, seeds=args.seeds)
            times["chunks"].append(result.summary["run_s"])
            returns["chunks"] = result.metrics["eval_return"]
            out = os.path.join(tmp, f"run{r}")
            run_dir.create(out, config, args.preset, args.seeds, 0)
            records, checkpoints = RecordsProcess(out), run_checkpoint.CheckpointWriter(out)
            result = run_training(
                config, seeds=args.seeds, on_ready=lambda _: records.start(),
                on_point=lambda step, means, returns, _: records.add_point(step, means, returns),
                on_checkpoint=checkpoints.save)
            closing = time.perf_counter()  # the last writes, the final checkpoint's included
            records.close_tensorboard()
            checkpoints.close()
            close_s = time.perf_counter() - closing
            records.close()
            times["followed"].append(result.summary["run_s"] + close_s)
            host.append((result.summary["host_s"] + close_s) / times["followed"][-1])
            returns["followed"] = result.metrics["eval_return"]
            print(json.dumps({k: round(v[-1], 3) for k, v in times.items()}), file=sys.stderr)

    def overhead(of, over):
        if over not in times:
            return None
        return round(100 * (statistics.median(a / b for a, b in zip(times[of], times[over])) - 1), 2)

    result = {"preset": args.preset, "seeds": args.seeds, "repeats": args.repeats,
              "total_steps": config.total_steps, "buffer_size": config.buffer_size,
              **{f"{k}_s": round(statistics.median(v), 3) for k, v in times.items()},
              "followed_host_pct": round(100 * statistics.median(host), 2),
              "overhead_pct_followed_vs_single_scan": overhead("followed", "single_scan"),
              "overhead_pct_followed_vs_chunks": overhead("followed", "chunks"),
              "overhead_pct_chunks_vs_single_scan": overhead("chunks", "single_scan"),
              **{f"{k}_all_s": [round(x, 3) for x in v] for k, v in times.items()},
              "followed_equals_chunks": bool(np.array_equal(
                  returns["followed"], returns["chunks"], equal_nan=True)),
              **{f"{k}_eval_returns": np.round(v.mean(axis=0), 1).tolist()
                 for k, v in returns.items()},
              "device": str(jax.devices()[0])}
    print(json.dumps(result))
    write_result(args.name or result_name(f"progress_overhead-{args.preset}"), result, source)


if __name__ == "__main__":
    main()
