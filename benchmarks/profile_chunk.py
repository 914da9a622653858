"""Where one training chunk's GPU time goes: kernels and kernel time by part of the iteration.

    python -m benchmarks.profile_chunk [--preset fast] [--seeds 1 256] [--hidden-dtype bfloat16]
                                       [--chunks 4] [--top 10]

`--preset rejax` profiles rejax's Pendulum-v1 configuration (`benchmarks.rejax_peer.CONFIG`).
For each seed count: compiles the chunk of the preset as `scripts/train.py --seeds S`
runs it on one device (`sac_jax.parallel.seeds_program`), runs `--chunks` chunks (the first
is the prefill), then one more under `jax.profiler.trace`. Each GPU kernel of that chunk is
mapped to the fused HLO instruction it runs (its name) and through that instruction's `op_name`
to the part of `sac_jax.train`'s iteration it comes from, by the named scopes there: act,
env_step, replay_add, replay_sample, sac_update, evaluate. Kernels of no part (loop counters,
copies between loop iterations, metric sums) count as "other". Prints one JSON line per seed
count: the compile and chunk seconds without the profiler, the profiled chunk's highest
evaluation return (for `fast`, InvertedPendulum-v5 scores 1 per step, so about its evaluation's
length in steps), and per part [kernels, kernel ms]; with `--top N`, each part's N kernels of
most time (kernel name, launches, ms, the tail of its op_name). Needs a GPU: a CPU trace holds
no kernels. All lines are written to benchmarks/results/NAME.json (`--name`, default
profile_chunk-KIND: profile_chunk-h100; command, machine, versions, date).
"""

from __future__ import annotations

import argparse
import collections
import dataclasses
import glob
import json
import os
import re
import tempfile
import time


import jax
from jax.profiler import ProfileData

from benchmarks.configurations import NAMES, configuration
from benchmarks.provenance import provenance, result_name, write_result
from sac_jax.parallel import seed_axis, seeds_program
from sac_jax.train import SEED_AXES, make_train_parts

PARTS = ("act", "env_step", "replay_add", "replay_sample", "sac_update", "evaluate")


def op_names(hlo_text: str) -> dict:
    """{HLO instruction name: its op_name} of the compiled program's text."""
    names = {}
    for line in hlo_text.splitlines():
        match = re.match(r'\s*(?:ROOT )?%?([\w.\-]+) = .*?op_name="([^"]*)"', line)
        if match:
            names[match.group(1)] = match.group(2)
    return names


def part_of(op_name: str) -> str:
    """The first of `PARTS` among the scopes of ``op_name``, or "other"."""
    return next((scope for scope in op_name.split("/") if scope in PARTS), "other")


def kernel_time_by_part(trace_dir: str, names: dict, top: int) -> tuple:
    """({part: [kernels, kernel ms]}, {part: its `top` kernels of most time}) of the GPU
    kernels in the trace under `trace_dir`; a kernel named `fusion_12` runs instruction
    `fusion.12` (`names`: its op_name)."""
    totals = collections.defaultdict(lambda: [0, 0.0])
    kernels = collections.defaultdict(lambda: [0, 0.0, ""])
    (path,) = glob.glob(os.path.join(trace_dir, "**", "*.xplane.pb"), recursive=True)
    for plane in ProfileData.from_file(path).planes:
        if "gpu" not in plane.name.lower():
            continue
        for line in plane.lines:
            if "stream" not in line.name.lower():
                continue
            for event in line.events:
                op_name = names.get(event.name) or names.get(
                    re.sub(r"_(\d+)$", r".\1", event.name), "")
                part = part_of(op_name)
                for entry in (totals[part], kernels[(part, event.name)]):
                    entry[0] += 1
                    entry[1] += event.duration_ns / 1e6
                kernels[(part, event.name)][2] = op_name[-120:]
    by_part = {part: [count, round(ms, 1)]
               for part, (count, ms) in sorted(totals.items(), key=lambda kv: -kv[1][1])}
    ranked = sorted(kernels.items(), key=lambda kv: -kv[1][1])
    tops = {part: [[name, count, round(ms, 2), op_name]
                   for (p, name), (count, ms, op_name) in ranked if p == part][:top]
            for part in by_part} if top else {}
    return by_part, tops


def profile(preset: str, seeds: int, hidden_dtype: str, chunks: int, top: int) -> dict:
    config = configuration(preset)
    config = dataclasses.replace(config, hidden_dtype=hidden_dtype or config.hidden_dtype)
    parts = make_train_parts(config, seed_axis=seed_axis(seeds))  # as sac_jax.run builds it
    init = seeds_program(parts.init, seeds, out_axes=SEED_AXES)
    chunk = seeds_program(parts.chunk, seeds, (SEED_AXES,), SEED_AXES, donate=True)
    state = init(jax.random.split(jax.random.key(0), seeds))
    start = time.perf_counter()
    compiled = chunk.lower(state).compile()
    compile_s = time.perf_counter() - start
    walls = []
    for _ in range(chunks):
        start = time.perf_counter()
        state = compiled(state)
        int(state.iteration)  # waits for the chunk
        walls.append(round(time.perf_counter() - start, 3))
    with tempfile.TemporaryDirectory() as trace_dir:
        with jax.profiler.trace(trace_dir):
            state = compiled(state)
            int(state.iteration)
        by_part, tops = kernel_time_by_part(trace_dir, op_names(compiled.as_text()), top)
    returns = jax.device_get(state.outputs["eval_return"])
    return {"preset": preset, "seeds": seeds, "hidden_dtype": config.hidden_dtype,
            "device": jax.devices()[0].device_kind, "compile_s": round(compile_s, 1),
            "chunk_s": walls,
            "profiled_chunk_max_eval_return": float(returns[:, chunks - 1].max()),
            "kernels_and_ms_by_part": by_part, **({"top_kernels": tops} if top else {})}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--preset", choices=NAMES, default="fast")
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 256])
    parser.add_argument("--hidden-dtype", choices=["float32", "bfloat16"], default=None,
                        help="the hidden layers' dtype (default: the preset's)")
    parser.add_argument("--chunks", type=int, default=4,
                        help="chunks run before the profiled one (the first is the prefill)")
    parser.add_argument("--top", type=int, default=0, help="kernels listed per part")
    parser.add_argument("--name", default=None, help="results file benchmarks/results/NAME.json "
                        "(default profile_chunk-KIND)")
    args = parser.parse_args(argv)
    source = provenance()
    rows = []
    for seeds in args.seeds:
        rows.append(profile(args.preset, seeds, args.hidden_dtype, args.chunks, args.top))
        print(json.dumps(rows[-1]), flush=True)
    write_result(args.name or result_name("profile_chunk"), {"rows": rows}, source)


if __name__ == "__main__":
    main()
