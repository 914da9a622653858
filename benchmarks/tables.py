"""The generated tables of BENCHMARKS.md and docs/performance.md (`DOCS`), written from
benchmarks/results/*.json, so that a figure and the run that produced it cannot drift apart.

    python -m benchmarks.tables            # rewrites every generated table in DOCS
    python -m benchmarks.tables --check    # exit 1 if a page differs from its results

    python -m benchmarks.tables --results DIR --print   # from other results, to stdout

A generated table stands between `<!-- generated: NAME -->` and `<!-- end generated -->` in
one of the pages; `TABLES[NAME]` writes it from the results files it names (each row or the
line above the table says which file and its date; the file holds its command, machine,
versions and date). Where a results file is missing, the table says so and which command
writes it.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import re
import statistics
import sys
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np

from benchmarks.points import reach_holds

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, "benchmarks", "results")
DOC = os.path.join(ROOT, "BENCHMARKS.md")
DOCS = (DOC, os.path.join(ROOT, "docs", "performance.md"))
"""The pages with generated tables: current figures, and the analyses behind those short of a
target."""
BLOCK = re.compile(r"(<!-- generated: (\S+) -->\n)(.*?)(<!-- end generated -->)", re.S)


PLAYGROUND_FAMILY = ("CartpoleBalance", "CartpoleSwingup", "PendulumSwingup", "AcrobotSwingup")
GPUS = ("h100", "h200")  # the kinds (benchmarks/provenance.py's machine_kind) of one GPU
CPUS_DELIVERED = (("delivered", "delivered-cold"), ("delivered-xeon", "delivered-cold-xeon"),
                  ("delivered-xeon26", "delivered-cold-xeon26"))
"""The README's command on each CPU model of the project's 2-core machines, the AMD EPYC, the
2.1 GHz Intel Xeon (whose files of 2026-11-29 record no clock), then a 2.6 GHz Intel Xeon:
(warm runs, `python -m benchmarks.delivered --name WARM`; cold starts, `python -m
benchmarks.delivered --seeds 0 --many 0 --cold 5 --name COLD`)."""
REJAX_OTHER_CPUS = ("rejax_peer-xeon26",)
"""rejax_peer's results on CPUs beside the AMD EPYC's `rejax_peer-cpu` (`--name`)."""


def _cpus_delivered() -> List[Tuple[str, str]]:
    """The (warm, cold) pairs of `CPUS_DELIVERED` whose warm runs are measured."""
    return [pair for pair in CPUS_DELIVERED if _find(pair[0])]


def _cpus_delivered_files() -> List[str]:
    """The results files of `_cpus_delivered` that exist, each CPU's warm file, then its cold."""
    return [name for pair in _cpus_delivered() for name in pair if _find(name)]


def _load(name: str) -> dict:
    with open(os.path.join(RESULTS, f"{name}.json")) as f:
        return json.load(f)


def _find(*names: str) -> Optional[str]:
    """The first of `names` whose results file exists."""
    return next((n for n in names if os.path.exists(os.path.join(RESULTS, f"{n}.json"))), None)


def _gpu(base: str) -> Optional[str]:
    """BASE-h100, else BASE-h200, where one exists."""
    return _find(*(f"{base}-{kind}" for kind in GPUS))


def _pending(command: str, where: str = "") -> str:
    return f"_not measured yet: run `{command}`{where}_\n"


def _machine(data: dict) -> str:
    m = data["provenance"]["machine"]
    kind = m.get("device_kind") or m.get("gpu")
    if kind and kind.lower() != "cpu":
        count = len(m.get("devices", [])) or 1
        return f"{count}x {kind}" if count > 1 else kind
    return f"CPU: {m['cpu']}, {m['cores']} cores"


def _cpu(data: dict) -> str:
    """The CPU model of a results file, without trademark signs, and its clock where recorded:
    "Intel Xeon 2.6 GHz", "AMD EPYC"."""
    machine = data["provenance"]["machine"]
    name = machine["cpu"].replace("(R)", "").replace(" Processor", "")
    clock = f" {machine['mhz'] / 1000:.1f} GHz" if machine.get("mhz") else ""
    return " ".join(name.split()) + clock


def _where(data: dict) -> str:
    """A table's machine cell: "CPU" for the page's usual AMD EPYC, "CPU (Intel Xeon)" for
    another CPU, else the accelerator (`_machine`)."""
    if data["provenance"]["machine"].get("device_kind", "cpu").lower() != "cpu":
        return _machine(data)
    return "CPU" if _cpu(data).startswith("AMD EPYC") else f"CPU ({_cpu(data)})"


def _from(name: str, data: dict) -> str:
    """The line above a one-file table: its file, date and machine."""
    return f"From `{name}.json` ({_date(data)}, {_machine(data)}):\n\n"


def _sources(sources, header: List[str], rows_of) -> str:
    """One table of the rows `rows_of(name, data)` of every present file of `sources` ([(name
    or None, command writing it)]), then a line per missing file naming its command."""
    rows, pending = [], []
    for name, command in sources:
        if name is None:
            pending.append(_pending(command))
        else:
            rows += rows_of(name, _load(name))
    text = _table(header, rows) if rows else ""
    return text + ("\n" if text and pending else "") + "\n".join(pending)


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


def _count(n: int, noun: str) -> str:
    return f"{n:,} {noun}" + ("" if n == 1 else "s")


def _table(header: List[str], rows: List[List[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def delivered_cpu() -> str:
    """The README's command per seed, cold starts and the many-seed run (CPU), per CPU model."""
    rows = []
    for name in _cpus_delivered_files():
        data = _load(name)
        result, date, cpu = data["result"], _date(data), _cpu(data)
        runs = result["runs"]
        if runs and not result.get("cold"):  # a cold file's warm seed: the warm file has it
            seeds = (f"seed {runs[0]['seed']}, warm cache" if len(runs) == 1 else
                     f"seeds {runs[0]['seed']}-{runs[-1]['seed']}, one run each")
            rows.append([f"{seeds} ({cpu})", date,
                         _span([r["solved_at_step"] for r in runs]),
                         _span([r["solved_wall_s"] for r in runs], "{:.1f}"),
                         f"median {np.median([r['solved_process_s'] for r in runs]):.1f}, max "
                         f"{max(r['solved_process_s'] for r in runs):.1f}",
                         _scores([r["gymnasium_return"] for r in runs]), f"`{name}.json`"])
        if result.get("cold"):
            cold, n = result["cold"], len(result["cold"].get("runs", [None]))
            compiles = [c["compile_s"] for c in result["cold"].get("runs", [])]
            rows.append([f"cold cache, seed 0 ({cpu})" + (f", median of {n} runs" if n > 1
                                                          else ""), date,
                         "-", "-", f"{cold['solved_process_s']:.1f} (compile "
                         f"{cold['compile_s']:.1f}" + (f"; {_span(compiles, '{:.1f}')})"
                                                       if n > 1 else ")"),
                         _scores([c["gymnasium_return"] for c in result["cold"].get(
                             "runs", [cold])]), f"`{name}.json`"])
        if result.get("many"):
            many = result["many"]
            rows.append([f"`--seeds {many['seeds']}` in one run, cache {many['cache']} ({cpu})",
                         date, f"{many['solved']}/{many['seeds']} solved",
                         f"last {many['all_solved_wall_s']:.1f}",
                         f"last {many['all_solved_process_s']:.1f}",
                         _scores(many["return"]), f"`{name}.json`"])
    if not rows:
        return _pending("python -m benchmarks.delivered --cold 5")
    return _table(["run", "date", "solved at step", "training s", "from process start s",
                   "Gymnasium return (10 episodes)", "results"], rows)


def delivered_gpu() -> str:
    """Seeds 0-2 alone and 256 seeds in one run (one GPU), scored in our environment."""
    def rows_of(name, data):
        rows = []
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
                     f"{min(many['return']):g} ({many.get('judged_in', 'ours')})",
                     f"`{name}.json`"])
        return rows

    return _sources([(_gpu("delivered"), "bash benchmarks/gpu.sh delivered"),
                     (_gpu("delivered-warm"), "bash benchmarks/gpu.sh delivered --warm-many "
                      "--name delivered-warm-KIND")],
                    ["run", "date", "training s", "from process start s",
                     "return (10 episodes)", "results"], rows_of)


def presets() -> str:
    """4 seeds of each preset; every delivered policy scored over 10 episodes."""
    def rows_of(name, data):
        return [[_where(data), f"`{run}`", f"{r['env']} ({r['threshold']:g}, {r['judged_in']})",
                 r.get("confirm_episodes", 20), f"{r['solved']}/{r['seeds']}",
                 _scores(r["scores"]), _date(data), f"`{name}.json`"]
                for run, r in data["result"].items()]

    return _sources([(_gpu("presets_delivered"), "bash benchmarks/gpu.sh presets"),
                     (_find("presets_delivered-cpu"), "python -m benchmarks.presets_delivered "
                      "--name presets_delivered-cpu")],
                    ["machine", "configuration", "task (solved, judged in)",
                     "confirmation episodes", "delivered ≥ solved", "scores", "date", "results"],
                    rows_of)


def _brax_rates(result) -> Tuple[Dict[str, Optional[float]], Optional[float]]:
    """Each trainer's median env steps/s from the start of training to its first solved point
    (`benchmarks.brax_peer`: the same steps for both; computed from the runs, as files before
    2026-11-30 hold Brax's rate over its whole run), and ours / Brax."""
    def rate(run):
        step, seconds = run["solved_at_step"], run["solve_train_s"]
        return None if step is None or not seconds else step / seconds

    medians = {}
    for who in ("brax", "ours"):
        rates = [rate(r[who]) for r in result["runs"]]
        medians[who] = None if None in rates else statistics.median(rates)
    ratio = (None if None in medians.values() else medians["ours"] / medians["brax"])
    return medians, ratio


def brax() -> str:
    """Brax's SAC against ours on the same physics (medians over the seeds)."""
    name = _gpu("brax_peer")
    if name is None:
        return _pending("bash benchmarks/gpu.sh brax --seeds 3", " on a GPU")
    data = _load(name)
    result, date = data["result"], _date(data)
    rates, rate_ratio = _brax_rates(result)
    rows = []
    for who, label in (("brax", "Brax SAC (first evaluation ≥ 950)"),
                       ("ours", "sac-jax (delivered policy)")):
        m = result["median"][who]
        steps = [r[who]["solved_at_step"] for r in result["runs"]]
        rows.append([label, date, f"{m['compile_s']:.1f}",
                     f"{m['solve_total_s']:.1f} ({m['solve_train_s']:.2f})", _span(steps),
                     "-" if rates[who] is None else f"{rates[who]:,.0f}", f"`{name}.json`"])
    ratio = result["ratio_ours_over_brax"]
    rows.append(["ours / Brax", "", f"{ratio['compile_s']:.2f}",
                 f"{ratio['solve_total_s']:.2f} ({ratio['solve_train_s']:.2f})", "",
                 "-" if rate_ratio is None else f"{rate_ratio:.2f}", ""])
    return _table(["trainer", "date", "compile s", "time to solved s (training only)",
                   "solved at step", "env steps/s to solved", "results"], rows)


def memory() -> str:
    """Peak memory per replay slot and per seed against their data, and `sac_jax.memory`'s
    estimate against the measured peak (CPU: peak RSS; a GPU: peak device bytes): its range
    over the grid's runs, and the largest run the memory check accepted."""
    def rows_of(name, data):
        r = data["result"]
        where, key = _where(data), ("peak_host_bytes" if name == "memory"
                                    else "peak_device_bytes")
        ratio = lambda m: m["memory_model_peak_bytes"] / m[key]
        grid = list(r.get("estimate_over_peak", {}).values())
        m = r.get("largest", {})
        if "failed" in m:  # estimated to fit, but the process did not finish
            largest = (f"{m['seeds']:,} seeds x {m['buffer_size']:,} slots: **failed** "
                       f"({m['failed'] or 'killed, out of memory'}), estimated to fit in 90 % "
                       f"of {m['available_bytes'] / 1e9:.1f} GB")
        else:
            largest = ("-" if key not in m else
                       f"{m['seeds']:,} seeds x {m['buffer_size']:,} slots: "
                       f"{m[key] / 1e9:.2f} GB, estimate {ratio(m):.2f}x")
        return [[where, f"{r['bytes_per_slot']:.1f} / {r['slot_data_bytes']} "
                        f"({r['per_slot_over_data']:.2f}x)",
                 f"{r['bytes_per_seed'] / 1e6:.2f} / {r['seed_data_bytes'] / 1e6:.2f} MB "
                 f"({r['seed_buffer_size']:,} slots)",
                 _span(grid, "{:.2f}") + f" ({len(grid)} runs)"
                 if grid else "-", largest, _date(data), f"`{name}.json`"]]

    return _sources([(_find("memory"), "python -m benchmarks.memory --largest 1000000"),
                     (_gpu("memory"), "bash benchmarks/gpu.sh memory")],
                    ["machine", "peak / data bytes per replay slot",
                     "per seed, its buffer included", "estimate / peak, 1-64 seeds, 10^4-10^7 "
                     "slots", "largest accepted run", "date", "results"], rows_of)


# The commands that write the results files of the tables below (BENCHMARKS.md's sizes).
ENV_GPU = "bash benchmarks/gpu.sh env --sizes 8 1280 131072 --steps 1000 --lean-stages on off"
ENV_CPU = ("python -m benchmarks.env_throughput --sizes 8 1280 --steps 1000 --lean-stages off on "
           "--gym-steps 5000 --rollout-steps 50")
UPDATES_CPU = "python -m benchmarks.update_throughput --updates 100 --rounds 10"
SCALING_GPU = "bash benchmarks/gpu.sh updates --seeds 1 256 --hidden-dtype float32 bfloat16"
SCALING_CPU = "python -m benchmarks.seed_scaling --seeds 1 2 --hidden-dtype float32 bfloat16"
TORCH_CPU = "python -m benchmarks.torch_time_to_solve --threads 2"
PROGRESS_CPU = {"fast": "python -m benchmarks.progress_overhead --repeats 9",
                "pendulum": "python -m benchmarks.progress_overhead --preset pendulum --repeats 9"}
PROGRESS_GPU = {"fast": "bash benchmarks/gpu.sh progress --seeds 256 --repeats 7 --no-single-scan"}
PARALLEL_GPUS = "bash benchmarks/gpu.sh parallel"  # on a host of 2 GPUs


def _env_rows(name: str, data: dict) -> List[List[str]]:
    """A row per backend and size: its default lean-stages setting, and the other beside it."""
    result, date = data["result"], _date(data)
    default = result.get("default_lean_stages")
    groups = {}
    for r in result["rows"]:
        groups.setdefault((r["backend"], r["instances"], r["steps"]), []).append(r)
    rows = []
    for (backend, instances, steps), rs in groups.items():
        main = next((r for r in rs if r["lean_stages"] in (None, default)), rs[0])
        other = next((r for r in rs if r is not main), None)
        compile_s = "-" if main["compile_s"] is None else f"{main['compile_s']:.1f}"
        rows.append([backend, f"{instances:,}", f"{steps:,}", compile_s,
                     f"{main['env_steps_per_s']:,.0f}" + (f" ({main['lean_stages']})"
                                                          if main["lean_stages"] else ""),
                     "-" if other is None else
                     f"{other['env_steps_per_s']:,.0f} ({other['lean_stages']})",
                     date, f"`{name}.json`"])
    return rows


ENV_HEADER = ["backend", "instances", "steps each", "compile s",
              "env steps/s (lean RK4 stages: default)", "lean stages flipped", "date", "results"]


def env() -> str:
    """MJX's env steps/s on one GPU and on the CPU, lean RK4 stages on and off, and on the CPU
    C MuJoCo (Gymnasium's loop, mujoco.rollout)."""
    return _sources([(_gpu("env_throughput"), ENV_GPU), (_find("env_throughput-cpu"), ENV_CPU)],
                    ENV_HEADER, _env_rows)


UPDATE_FIGURES = [  # key, label, format, scale, target
    ("ours", "sac_jax `sac_update` (scan), updates/s", "{:.1f}", 1, None),
    ("theirs", "PyTorch seed-002 loop, updates/s", "{:.1f}", 1, None),
    ("speedup", "ours / PyTorch, per round", "{:.2f}x", 1, 2.0),
    ("peak", "JAX 1024^3 matmul, GFLOP/s", "{:.1f}", 1e-9, None),
    ("layer", "JAX chain at the layer shape, GFLOP/s", "{:.1f}", 1e-9, None),
    ("of_peak", "ours / 1024^3 roofline, per round", "{:.0%}", 1, 0.70),
    ("of_layer", "ours / layer-shape rate, per round", "{:.0%}", 1, None)]


def updates_cpu() -> str:
    """`sac_update` against the PyTorch seed-002 update loop and the roofline (CPU)."""
    name = _find("update_throughput-cpu")
    if name is None:
        return _pending(UPDATES_CPU)
    data = _load(name)
    r = data["result"]
    rows = []
    for key, label, fmt, scale, target in UPDATE_FIGURES:
        med = r["median"][key]
        status = "" if target is None else (
            f"≥ {fmt.format(target)}: " + ("**met**" if med >= target else "not met"))
        rows.append([label, f"**{fmt.format(med * scale)}**" if target else
                     fmt.format(med * scale), f"{fmt.format(r['min'][key] * scale)} - "
                     f"{fmt.format(r['max'][key] * scale)}", status])
    return _from(name, data) + _table(
        [f"figure ({r['rounds']} rounds of {r['updates']} updates)", "median",
         "range over rounds", "target"], rows)


def seed_scaling() -> str:
    """Updates/s of many seeds vmapped, float32 against bfloat16 hidden layers (GPU, CPU)."""
    def rows_of(name, data):
        rates = {(r["seeds"], r["hidden_dtype"]): r["updates_per_s"]
                 for r in data["result"]["rows"]}
        rows = []
        for seeds in sorted({s for s, _ in rates}):
            f32, b16 = rates.get((seeds, "float32")), rates.get((seeds, "bfloat16"))
            rows.append([_machine(data), f"{seeds:,}",
                         "-" if f32 is None else f"{f32:,.0f}",
                         "-" if b16 is None else f"{b16:,.0f}",
                         "-" if None in (f32, b16) else f"{b16 / f32:.2f}x",
                         _date(data), f"`{name}.json`"])
        return rows
    return _sources([(_gpu("seed_scaling"), SCALING_GPU),
                     (_find("seed_scaling-cpu"), SCALING_CPU)],
                    ["machine", "seeds vmapped", "float32, updates/s",
                     "bfloat16 hidden layers, updates/s", "bfloat16 / float32", "date",
                     "results"], rows_of)


def torch_loop() -> str:
    """The PyTorch seed-002 loop's time to a first evaluation ≥ 950, beside ours (CPU)."""
    name = _find("torch_time_to_solve-cpu")
    if name is None:
        return _pending(TORCH_CPU)
    data = _load(name)
    r, date = data["result"], _date(data)
    runs = r["runs"]
    steps = [x["solved_at_step"] for x in runs if x["solved_at_step"] is not None]
    median = r["median"]
    cpu = data["provenance"]["machine"]
    rows = [[f"PyTorch seed-002 loop, {_count(r['threads'], 'thread')} of {cpu['cpu']} "
             f"({cpu['cores']} cores), {_count(len(runs), 'seed')}",
             f"{len(steps)}/{len(runs)} solved" + (f", at {_span(steps)}" if steps else ""),
             "-" if median["solve_wall_s"] is None else f"**{median['solve_wall_s']:.1f}**",
             f"{median['env_steps_per_s']:,.1f}", f"{median['updates_per_s']:,.1f}", date,
             f"`{name}.json`"]]
    for ours, label in (("delivered", "sac-jax `fast`, warm cache"),
                        ("delivered-cold", "sac-jax `fast`, cold cache")):
        if _find(ours) is None:
            continue
        d = _load(ours)
        res = d["result"]
        solved = [x for x in res["runs"] if x["solved_process_s"] is not None]
        if ours == "delivered" and solved:
            rows.append([label + ", its delivered policy confirmed",
                         f"{len(solved)}/{len(res['runs'])} solved, at "
                         f"{_span([x['solved_at_step'] for x in solved])}",
                         f"**{statistics.median(x['solved_process_s'] for x in solved):.1f}** "
                         "(median of the solved)", "-", "-", _date(d), f"`{ours}.json`"])
        if ours == "delivered-cold" and res.get("cold") and res["cold"]["solved_process_s"]:
            colds = res["cold"].get("runs", [res["cold"]])
            rows.append([label + ", its delivered policy confirmed",
                         f"{sum(c['solved_process_s'] is not None for c in colds)}/"
                         f"{len(colds)} runs of seed {res['runs'][0]['seed']} solved",
                         f"**{res['cold']['solved_process_s']:.1f}**"
                         + (f" (median of {len(colds)})" if len(colds) > 1 else ""), "-", "-",
                         _date(d), f"`{ours}.json`"])
    return _table(["trainer", "seeds solved", "s to solved (from process start for ours)",
                   "env steps/s", "updates/s", "date", "results"], rows)


def progress() -> str:
    """Host time spent following a run: progress, TensorBoard, checkpoints (CPU; an H100)."""
    def rows_of(name, data):
        r = data["result"]
        return [[name.rsplit("-", 1)[-1], f"`{r['preset']}` ({r.get('total_steps', 0):,} steps, "
                 f"{r.get('buffer_size', 0):,}-slot buffer), {_count(r['seeds'], 'seed')}, "
                 f"{_count(r['repeats'], 'repeat')}", f"{r['chunks_s']:.2f}",
                 f"{r['followed_s']:.2f}",
                 f"{r['overhead_pct_followed_vs_chunks']:+.1f} %",
                 f"**{r['followed_host_pct']:.2f} %**" + (" (≤ 5 %: met)" if
                                                        r["followed_host_pct"] <= 5 else
                                                        " (≤ 5 %: not met)"),
                 _date(data), f"`{name}.json`"]]
    return _sources([(_find(f"progress_overhead-{preset}-cpu"), command)
                     for preset, command in PROGRESS_CPU.items()] +
                    [(_gpu(f"progress_overhead-{preset}"), command)
                     for preset, command in PROGRESS_GPU.items()],
                    ["device", "preset", "chunks s", "followed s", "followed / chunks", "host share",
                     "date", "results"], rows_of)


def _parallel_files() -> List[str]:
    names = [os.path.basename(p)[:-5] for p in glob.glob(os.path.join(RESULTS,
                                                                      "data_parallel-*.json"))]
    def key(name):
        c = _load(name)["result"]["config"]
        return c["num_envs"], c["repeats"], name
    return sorted(names, key=key)


def parallel() -> str:
    """One GPU against data parallel over all of one host's GPUs."""
    names = _parallel_files()
    if not names:
        return _pending(PARALLEL_GPUS, " on a host of 2 GPUs")
    rows = []
    for name in names:
        data = _load(name)
        r = data["result"]
        c, one, two = r["config"], r["one_device"], r["data_parallel"]
        rows.append([f"{c['num_envs']:,}", f"{c['batch_size']:,}", c["repeats"],
                     f"{one['env_steps_per_s']:,.0f} ({one['updates_per_s']:,.0f})",
                     f"{two['env_steps_per_s']:,.0f} ({two['updates_per_s']:,.0f})",
                     f"**{r['speedup']:.2f}x**" if r["speedup"] >= 1.8 else
                     f"{r['speedup']:.2f}x", f"{one['compile_s']:.1f} / {two['compile_s']:.1f}",
                     f"{r['devices']}x {r['device_kind']}", _date(data), f"`{name}.json`"])
    return _table(["environments", "batch", "repeats", "one GPU: env steps/s (updates/s)",
                   "all GPUs, data parallel", "speedup", "compile s (one / all)", "machine",
                   "date", "results"], rows)


def _target_cpu_updates():
    name = _find("update_throughput-cpu")
    if name is None:
        return None
    r = _load(name)["result"]
    return [name], [(f"{r['median']['speedup']:.2f}x (median of {r['rounds']} rounds)",
                     r["median"]["speedup"] >= 2.0),
                    (f"{r['median']['of_peak']:.0%} ({r['median']['of_layer']:.0%} of the "
                     "layer shape's rate)", r["median"]["of_peak"] >= 0.70)]


def _target_delivered_cpu():
    pairs = _cpus_delivered()
    if not pairs:
        return None
    good, warm, cold, met = [], [], [], True
    for warm_name, cold_name in pairs:
        data = _load(warm_name)
        runs, many = data["result"]["runs"], data["result"]["many"] or {}
        times = [r["solved_process_s"] for r in runs]
        seeds_good = sum(r["gymnasium_return"] >= 950 for r in runs)
        many_good = sum(x >= 950 for x in many.get("return", []))
        good.append(f"{seeds_good}/{len(runs)} seeds and {many_good}/{many.get('seeds', 0)} of "
                    "one run")
        warm.append(f"{_cpu(data)} median {statistics.median(times):.1f} s, slowest "
                    f"{max(times):.1f} s")
        first = _load(cold_name)["result"].get("cold") if _find(cold_name) else None
        colds = [c["solved_process_s"] for c in first.get("runs", [first])] if first else []
        cold.append(f"{_cpu(data)} " + (f"median {first['solved_process_s']:.1f} s, slowest "
                                        f"{max(colds):.1f} s" if first else "not measured"))
        cold_good = first and all(c["gymnasium_return"] >= 950
                                  for c in first.get("runs", [first]))
        met &= bool(len(runs) >= 10 and seeds_good == len(runs) and many
                    and many["seeds"] >= 32 and many_good == many["seeds"]
                    and max(times) <= 10 and cold_good and max(colds) <= 25)
    figure = (f"{'; '.join(dict.fromkeys(good))} ≥ 950; warm: {'; '.join(warm)}; cold: "
              f"{'; '.join(cold)}")
    return sorted(_cpus_delivered_files()), [(figure, met)]


def _target_presets():
    name = _gpu("presets_delivered")
    if name is None:
        return None
    result = _load(name)["result"]
    parts = [f"`{run}` {r['solved']}/{r['seeds']}" + (
        f" ({r['confirm_episodes']} confirmation episodes)"
        if r.get("confirm_episodes", 20) != 20 else "") for run, r in result.items()]
    # the target's scope: cleanrl, pendulum, v1 and InvertedDoublePendulum, 4 seeds each
    met = (len(result) >= 4 and all(r["seeds"] >= 4 and r["solved"] == r["seeds"]
                                    for r in result.values()))
    return [name], [("; ".join(parts), met)]


def _target_delivered_gpu():
    name = _gpu("delivered-warm")
    if name is None:
        return None
    r = _load(name)["result"]
    many, runs = r["many"], r["runs"]
    one = statistics.median(x["solved_process_s"] for x in runs)
    one_train = statistics.median(x["solved_wall_s"] for x in runs)
    ratio = many["all_solved_process_s"] / one
    figure = (f"{many['at_least_950']}/{many['seeds']} ≥ 950; from process start "
              f"{many['all_solved_process_s']:.1f} s against {one:.1f} s (median of one-seed "
              f"runs), **{ratio:.1f}x**; in training seconds "
              f"{many['all_solved_wall_s'] / one_train:.1f}x")
    return [name], [(figure, many["seeds"] >= 256 and many["at_least_950"] >= many["seeds"] - 1
                     and ratio <= 2)]


def _target_brax():
    names = [n for n in (_gpu("brax_peer"), _find("brax_peer-cpu")) if n]
    if not names:
        return None
    parts, met = [], True
    for name in names:
        data = _load(name)
        ratio, rate_ratio = data["result"]["ratio_ours_over_brax"], _brax_rates(data["result"])[1]
        if None in (ratio["solve_total_s"], rate_ratio):  # a trainer unsolved
            parts.append(f"{_machine(data)}: not both solved")
            met = False
            continue
        parts.append(f"{_machine(data)}: {ratio['solve_total_s']:.2f}x the time, "
                     f"{rate_ratio:.2f}x the env steps/s to solved")
        met = met and ratio["solve_total_s"] < 1 and rate_ratio > 1
    return names, [("; ".join(parts), met)]


def _target_env_gpu():
    name = _gpu("env_throughput")
    if name is None:
        return None
    best = max((r for r in _load(name)["result"]["rows"] if r["backend"].startswith("MJX")),
               key=lambda r: r["env_steps_per_s"])
    return [name], [(f"{best['env_steps_per_s']:,.0f} ({best['instances']:,} instances)",
                     best["env_steps_per_s"] >= 3e6)]


def _target_progress():
    """The host's share of a followed run, every CPU preset and the GPU's 256-seed run."""
    names = [n for n in [_find(f"progress_overhead-{p}-cpu") for p in PROGRESS_CPU]
             + [_gpu("progress_overhead-fast")] if n]
    if not names:
        return None
    results = [(n, _load(n)["result"]) for n in names]
    cpu = {r["preset"] for n, r in results if n.endswith("-cpu")}
    missing = [p for p in PROGRESS_CPU if p not in cpu]
    where = lambda n: "CPU" if n.endswith("-cpu") else n.rsplit("-", 1)[-1].upper()
    met = all(r["followed_host_pct"] <= 5 for _, r in results)
    return names, [(", ".join(f"{where(n)} `{r['preset']}` {r['seeds']} seed(s) "
                              f"{r['followed_host_pct']:.2f} %" for n, r in results) +
                    "".join(f", CPU `{p}` not measured yet" for p in missing),
                    None if (missing or len(cpu) == len(results)) and met else met)]


def _target_checkpoint_cost():
    """Issue 25's bound: a followed run (progress, TensorBoard, checkpoints) over the bare
    chunked run, on the CPU and a 256-seed H100 run."""
    names = [n for n in [_find(f"progress_overhead-{p}-cpu") for p in PROGRESS_CPU]
             + [_gpu("progress_overhead-fast")] if n]
    if not names:
        return None
    results = [(n, _load(n)["result"]) for n in names]
    on_gpu = lambda n: not n.endswith("-cpu")
    figure = ", ".join(f"{n.rsplit('-', 1)[-1].upper() if on_gpu(n) else 'CPU'} "
                       f"`{r['preset']}` {r['seeds']} seed(s) "
                       f"{r['overhead_pct_followed_vs_chunks']:+.1f} %" for n, r in results)
    met = all(r["overhead_pct_followed_vs_chunks"] <= 2 for _, r in results)
    gpu = any(on_gpu(n) and r["seeds"] >= 256 for n, r in results)
    return names, [(figure, met if gpu or not met else None)]


def _playground_files() -> List[str]:
    return [n for n in (_find("playground_adapter-cpu"), _gpu("playground_adapter")) if n]


def playground() -> str:
    """Playground's raw task step against our adapter's, per task and machine, per backend."""
    def rows(name, data):
        where = _where(data)
        groups = {}
        for r in data["result"]["rows"]:
            groups.setdefault(r["task"], []).append(r)
        return [[task, where, f"{rs[0]['envs']:,}"] + [
            "; ".join(f"{r['impl']}: {r['steps_per_s'][part]:,.0f}" for r in rs)
            for part in ("raw", "adapter")] + [
            "; ".join(f"{r['impl']}: {100 * r['overhead']:+.1f} %" for r in rs)]
            for task, rs in groups.items()]

    return _sources([(_find("playground_adapter-cpu"), "python -m benchmarks.playground_adapter"),
                     (_gpu("playground_adapter"),
                      "bash benchmarks/gpu.sh playground_adapter --envs 4096 --steps 200")],
                    ["task", "machine", "instances", "raw steps/s", "adapter steps/s",
                     "adapter overhead"], rows)


def _peer_files() -> List[str]:
    return [n for n in (_gpu(f"playground_peer-{task}") for task in PLAYGROUND_FAMILY) if n]


def playground_peer() -> str:
    """Playground's SAC (Brax, its tuned config) against ours, per task, on one GPU."""
    def rows(name, data):
        r = data["result"]
        one, many = r["ours"]["1"], r["ours"][str(max(int(n) for n in r["ours"]))]
        def reached(run):
            fresh = ("" if "fresh" not in run else
                     f"; delivered: {np.mean(run['fresh']):.1f} over fresh episodes")
            if run["to_peer_final"] is not None:
                return (f"{run['to_peer_final']['seconds']:.1f} s, "
                        f"{run['to_peer_final']['env_steps']:,} steps{fresh}")
            step, _, stopped, _ = run["points"][-1]  # the budget's end
            return (f"{round(stopped * run['seeds'])}/{run['seeds']} reached it in {step:,} "
                    f"steps{fresh}")

        singles = r.get("single_runs") or []  # `--runs N`: one is the median of N runs
        if len(singles) > 1:
            each = ", ".join(f"{run['to_peer_final']['seconds']:.1f} s" if run["to_peer_final"]
                             else "not reached" for run in singles)
            one_cell = (f"median of {len(singles)} runs (seeds {singles[0]['seed']}-"
                        f"{singles[-1]['seed']}: {each}): {reached(one)}")
        else:
            one_cell = reached(one)
        if r.get("one_seed_from"):  # `--runs 0`: measured beside the peer, in an earlier job
            one_cell += f" (an earlier job, {r['one_seed_from']['date'][:16]})"
        peer_steps = r["peer_arguments"]["num_timesteps"]
        earlier = r.get("peer_from")  # the peer ran in an earlier job (`--peer-from`)
        margin = r.get("stop_margin")  # ours stopped that far above it (`--stop-margin`)
        variant = r.get("variant")  # the preset's fields ours replaced (`--variant`)
        task = r["task"] + (" (" + ", ".join(f"{k} {v}" for k, v in variant.items()) + ")"
                            if variant else "")
        return [[task, _machine(data), f"{r['peer']['final_return']:.1f}"
                 + (f" (ours stopping at +{margin:g})" if margin else ""),
                 f"{r['peer']['wall_s']:.0f} s, {peer_steps:,} steps"
                 + (f" (an earlier job, {earlier['date'][:16]})" if earlier else ""), one_cell,
                 f"{many['seeds']}: {reached(many)}",
                 "-" if r["ours_over_peer_time"] is None else f"{r['ours_over_peer_time']:.2f}x",
                 "-" if r["seeds_over_one_time"] is None else f"{r['seeds_over_one_time']:.2f}x"]]

    sources = [(_gpu(f"playground_peer-{task}"),
                f"bash benchmarks/gpu.sh playground --task {task}") for task in PLAYGROUND_FAMILY]
    return _sources(sources, ["task", "GPU", "peer's final return", "peer: wall time, budget",
                              "ours, 1 seed: to that return", "ours, seeds vmapped",
                              "time, ours / peer", "time, seeds / 1 seed"], rows)


def _target_playground_peer():
    names = _peer_files()
    if not names:
        return None
    results = [_load(n)["result"] for n in names]
    complete = len(names) == len(PLAYGROUND_FAMILY)

    def figure(key, limit):
        # a reach counts only where every delivered actor scored the peer's return on fresh
        # episodes (the time ratio rests on one seed's run, the seeds ratio on both)
        runs = {r["task"]: [(r["ours"]["1"], r)] if key == "ours_over_peer_time"
                else [(run, r) for run in r["ours"].values()] for r in results}
        holds = {task: [run.get("reach_holds", "unscored") if "fresh" not in run
                        or run["to_peer_final"] is None
                        else reach_holds(run["fresh"], r["peer"]["final_return"])
                        for run, r in rs] for task, rs in runs.items()}
        why = {task: "" if all(x is True for x in h) else " (not held on fresh episodes)"
               if False in h else " (not scored on fresh episodes)" for task, h in holds.items()}
        values = {r["task"]: r[key] for r in results}
        met = all(v is not None and v <= limit and not why[task] for task, v in values.items())
        return (", ".join(f"{task} " + ("not reached" if v is None else f"{v:.2f}x")
                          + ("" if v is None else why[task]) for task, v in values.items())
                + ("" if complete else f" ({len(names)} of {len(PLAYGROUND_FAMILY)} tasks)"),
                met if complete or not met else None)

    return names, [figure("ours_over_peer_time", 1 / 3), figure("seeds_over_one_time", 2.0)]


def _target_playground_cpu():
    """Issue 24's CPU target, from `python -m benchmarks.delivered --preset CartpoleBalance`."""
    name = _find("delivered-CartpoleBalance")
    if name is None:
        return None
    result = _load(name)["result"]
    cold, solved = result["cold"]["runs"], result["solved_return"]
    fresh = [r["fresh_return"] for r in result["runs"]]
    times = [np.inf if c["solved_process_s"] is None else c["solved_process_s"] for c in cold]
    figure = (f"{sum(f >= solved for f in fresh)}/{len(fresh)} seeds ≥ {solved:g} over "
              f"{result['episodes']} fresh episodes each (lowest {min(fresh):.1f}); cold, "
              f"seed 0: median {statistics.median(times):.1f} s from process start to solved, "
              f"slowest {max(times):.1f} s ({len(cold)} runs)")
    fresh += [c["fresh_return"] for c in cold]
    return [name], [(figure, min(fresh) >= solved and max(times) <= 180)]


def rejax() -> str:
    """rejax against ours on rejax's tuned Pendulum-v1 SAC: its program, our program, our script."""
    def rows(name, data):
        where = _where(data)
        out = []
        for r in data["result"]["rows"]:
            j, p, cold, warm = r["rejax"], r["program"], r["script_cold"], r["script_warm"]
            rounds = r["to_result_rounds"]
            rejax_s, warm_s = (statistics.median(rounds[k]) for k in ("rejax", "ours_warm"))
            cached = (f"{statistics.median(rounds['rejax_warm']):.1f}"
                      if "rejax_warm" in rounds else "-")
            both = r.get("rejax_warm_over_script_to_result_warm")
            script_s = statistics.median(rounds.get("ours_warm_run", [warm["run_s"]]))
            out.append([where, r["seeds"], f"{j['compile_s']:.1f} + {j['run_s']:.2f} s",
                        f"{p['compile_s']:.1f} + {p['run_s']:.2f} s",
                        f"{script_s:.2f} s ({r['script_over_program']:.2f}x)"
                        + (f", {warm['seed_devices']} devices" if warm.get("seed_devices", 1) > 1
                           else ""),
                        f"{rejax_s:.1f} / {cached} / {cold['to_result_s']:.1f} / {warm_s:.1f} s"
                        + (f" (warm: medians of {len(rounds['rejax'])})"
                           if len(rounds["rejax"]) > 1 else ""),
                        f"{r['rejax_over_script_to_result_cold']:.2f}x / "
                        f"{r['rejax_over_script_to_result_warm']:.2f}x / "
                        + ("-" if both is None else f"{both:.2f}x"),
                        f"{_mean(j['final_return_per_seed']):.0f} / {_mean(p['final_per_seed']):.0f}"])
        return out

    return _sources([(_find("rejax_peer-cpu"), "python -m benchmarks.rejax_peer --rejax-python "
                      "PATH")] + [(n, None) for n in REJAX_OTHER_CPUS if _find(n)]
                    + [(_gpu("rejax_peer"), "python -m benchmarks.rejax_peer on a GPU")],
                    ["machine", "seeds", "rejax: compile + run", "our program: compile + run",
                     "our script: run (/ program)",
                     "process start to result: rejax / rejax, its cache warm / ours cold / "
                     "ours warm",
                     "rejax / ours: cold / ours warm / both warm", "final return rejax / ours"],
                    rows)


def _rejax_files() -> List[str]:
    """rejax_peer's results files that exist: the AMD EPYC's, other CPUs', then a GPU's."""
    return [n for n in (_find("rejax_peer-cpu"), *(_find(n) for n in REJAX_OTHER_CPUS),
                        _gpu("rejax_peer")) if n]


def _rejax_where(name: str) -> str:
    """A target's machine word: "CPU" (the AMD EPYC), "CPU Intel Xeon 2.6 GHz", or "GPU"."""
    if name in {f"rejax_peer-{kind}" for kind in GPUS}:
        return "GPU"
    cpu = _cpu(_load(name))
    return "CPU" if cpu.startswith("AMD EPYC") else f"CPU {cpu}"


def _cpu_and_gpu(names: List[str]) -> bool:
    """Whether `names` hold a CPU's figures and a GPU's, as the rejax targets need."""
    return len({_rejax_where(n) == "GPU" for n in names}) == 2


def _target_rejax(key: str, limit: float, above: bool):
    names = _rejax_files()
    if not names:
        return None
    parts, met = [], True
    for name in names:
        where = _rejax_where(name)
        for r in _load(name)["result"]["rows"]:
            if key not in r:  # a file from before the figure was measured
                parts.append(f"{where} {r['seeds']} seed(s) not measured yet")
                met = None if met else met
                continue
            devices = r["script_warm"].get("seed_devices", 1)  # the program ran on one
            if devices > 1 and key == "script_over_program":  # not the same program
                parts.append(f"{where} {r['seeds']} seed(s) {r[key]:.2f}x (the script on "
                             f"{devices} devices, the program on one: not counted)")
                continue
            parts.append(f"{where} {r['seeds']} seed(s) {r[key]:.2f}x")
            if met is not None:
                met = met and (r[key] >= limit if above else r[key] <= limit)
    return names, [("; ".join(parts), met if _cpu_and_gpu(names) or met is False else None)]


def _target_evaluation_share():
    rows = [(name, r) for name in _rejax_files() for r in _load(name)["result"]["rows"]
            if "evaluation_share" in r]
    if not rows:
        return None
    met = all(r["evaluation_share"] <= 0.10 for _, r in rows)
    names = list(dict.fromkeys(name for name, _ in rows))
    return names, [("; ".join(f"{_rejax_where(name)} {r['seeds']} seed(s) "
                              f"{100 * r['evaluation_share']:.1f} %" for name, r in rows),
                    met if _cpu_and_gpu(names) or not met else None)]


def _target_cold_compile():
    cpus = [cold for _, cold in _cpus_delivered()]
    names = [n for n in cpus + [_gpu("delivered-cold")] if n and _find(n)
             and _load(n)["result"].get("cold")]
    if not names:
        return None
    colds = {n: _load(n)["result"]["cold"] for n in names}
    met = all(c["compile_s"] <= 10.0 for c in colds.values())
    of = lambda c: (f" (median of {len(c['runs'])}: "
                    f"{_span([r['compile_s'] for r in c['runs']], '{:.1f}')})"
                    if len(c.get("runs", [])) > 1 else "")
    where = lambda n: f"CPU {_cpu(_load(n))}" if n in cpus else "GPU"
    both = any(n in cpus for n in names) and any(n not in cpus for n in names)
    return names, [("; ".join(f"{where(n)} {c['compile_s']:.1f} s{of(c)}"
                              for n, c in colds.items()),
                    met if both else (None if met else False))]


def compile_options() -> str:
    """A first run's compile seconds and a warm run's training seconds per set of XLA flags."""
    name = _gpu("compile_options")
    if name is None:
        return _pending("bash benchmarks/gpu.sh compile --variant= --variant=FLAGS ...")
    data, runs = _load(name), {}
    for r in data["result"]["variants"]:
        if "error" not in r:
            runs.setdefault(r["xla_flags"], []).append(r)
    median = statistics.median
    rows = [[f"`{flags}`" if flags else "XLA's defaults", len(rs),
             f"{_span([r['cold']['compile_s'] for r in rs], '{:.1f}')} (median "
             f"{median(r['cold']['compile_s'] for r in rs):.1f})",
             f"{median(r['warm']['solved_wall_s'] for r in rs):.2f}"]
            for flags, rs in runs.items()]
    return _from(name, data) + _table(["XLA flags", "runs", "cold compile s",
                                       "median training to solved s (warm)"], rows)


def _mean(values) -> float:
    return sum(values) / len(values)


def _target_playground_adapter():
    names = _playground_files()
    if not names:
        return None
    worst = max(_load(n)["result"]["worst_overhead"] for n in names)
    gpu = len(names) > 1
    return names, [(f"worst {100 * worst:+.1f} % over "
                    f"{sum(len(_load(n)['result']['rows']) for n in names)} task/backend rows"
                    + ("" if gpu else " (CPU only)"),
                    (worst <= 0.05) if gpu else None)]


def _memory_files() -> List[str]:
    return [n for n in ("memory", _gpu("memory")) if n and _find(n)]


def _target_memory_per_slot():
    names = _memory_files()
    if not names:
        return None
    ratios = {n: _load(n)["result"]["per_slot_over_data"] for n in names}
    met = all(r <= 1.15 for r in ratios.values())
    return names, [("; ".join(f"`{n}`: {r:.2f}x" for n, r in ratios.items()),
                    met if len(names) == 2 else (None if met else False))]


def _target_memory():
    names = _memory_files()
    if not names:
        return None
    ratios = {n: _load(n)["result"].get("estimate_over_peak", {}) for n in names}
    low = {n: min(r.values()) for n, r in ratios.items() if r}
    high = {n: max(r.values()) for n, r in ratios.items() if r}
    figure = "; ".join(f"`{n}`: {low[n]:.2f}-{high[n]:.2f} over {len(ratios[n])} runs"
                       for n in low) or "no estimate recorded"
    met = bool(low) and all(0.75 <= low[n] and high[n] <= 1.25 for n in low)
    return names, [(figure, met if len(low) == 2 else (None if met else False))]


def _target_parallel():
    names = _parallel_files()
    if not names:
        return None
    results = [r for r in (_load(n)["result"] for n in names)
               if r["devices"] == 2 and r["device_kind"].lower() != "cpu"]
    names = [n for n in names if _load(n)["result"] in results]
    if not results:
        return None
    large = [r for r in results if r["config"]["num_envs"] >= 262_144]
    return names, [(", ".join(f"{r['speedup']:.2f}x ({r['config']['num_envs']:,})"
                              for r in results),
                    any(r["speedup"] >= 1.8 for r in large))]


SWEEP_CPU = "python -m benchmarks.sweep --warm"
SWEEP_GPU = "bash benchmarks/gpu.sh sweep --warm"


def _sweep_rows(name: str, data: dict) -> List[List[str]]:
    r, rows = data["result"], []
    for label in ("cold", "warm"):
        if label not in r:
            continue
        sweep, separate = r[label]["sweep"], r[label]["separate"]
        rows.append([f"{r['settings']} x {r['seeds']}, {label} cache", _machine(data),
                     _date(data), f"{sweep['process_wall_s']:.1f} (compile "
                     f"{sweep['compile_s']:.1f})", f"{sweep['solved']}/{sweep['runs']}",
                     f"{separate['runs']}: {separate['process_wall_s']:.1f}",
                     f"**{r[label]['ratio']:.2f}**", f"`{name}.json`"])
    return rows


def sweep() -> str:
    """A sweep in one program against the same runs one process each (process wall times)."""
    return _sources([(_find("sweep-cpu"), SWEEP_CPU), (_gpu("sweep"), SWEEP_GPU)],
                    ["settings x seeds", "machine", "date", "sweep s", "solved",
                     "separate runs: total s", "sweep / separate", "results"], _sweep_rows)


def _target_sweep(kind: str, limit: Optional[float]):
    """The sweep against separate runs, cold and warm; met where both ratios are within
    `limit` (None: a figure to report, met once measured)."""
    name = _find("sweep-cpu") if kind == "cpu" else _gpu("sweep")
    if name is None:
        return None
    r = _load(name)["result"]
    ratios = [r[label]["ratio"] for label in ("cold", "warm") if label in r]
    warm = f", warm {r['warm']['ratio']:.2f}x" if "warm" in r else ""
    figure = (f"{r['settings']} x {r['seeds']} in {ratios[0]:.2f}x the time of "
              f"{r['cold']['separate']['runs']} separate run(s) (cold{warm})")
    return [name], [(figure, "reported" if limit is None
                     else all(x <= limit for x in ratios))]


TARGETS = [  # (target, section, () -> ([results files], [(figure, met: True, False or None)])
    #          or None where nothing is measured, which of those (figure, met) pairs)
    ("CPU: `sac_update` ≥ 2x the PyTorch seed-002 update loop", "Gradient updates",
     _target_cpu_updates, 0),
    ("CPU: ≥ 70 % of the 1024^3 matmul rate", "Gradient updates", _target_cpu_updates, 1),
    ("CPU: the README's command delivers a policy scoring ≥ 950 in Gymnasium for ≥ 10 seeds "
     "and all of a `--seeds 32` run; process start to that policy ≤ 10 s warm (slowest seed), "
     "≤ 25 s cold (a quiet machine; slowest of the cold runs)", "Delivered policy",
     _target_delivered_cpu, 0),
    ("Presets `cleanrl`, `pendulum`, `v1` and InvertedDoublePendulum deliver the solved "
     "return on 4 of 4 seeds (GPU)", "Delivered policy", _target_presets, 0),
    ("GPU: 256 seeds in one run, ≥ 255/256 deliver ≥ 950, from process start to all "
     "delivered ≤ 2x one seed's (warm cache)", "Delivered policy", _target_delivered_gpu, 0),
    ("Brax's SAC on the same physics: ahead on time to solve and env steps/s",
     "Brax's SAC and the PyTorch seed on the same task", _target_brax, 0),
    ("GPU: ≥ 3M env steps/s", "Environment throughput", _target_env_gpu, 0),
    ("Following a run (progress, TensorBoard, checkpoints): ≤ 5 % of its time on the host, "
     "CPU presets and 256 seeds on one GPU",
     "Following a run", _target_progress, 0),
    ("Following a run costs ≤ 2 % of the bare chunked run (followed / chunks), on the CPU "
     "and on one GPU with 256 seeds", "Following a run", _target_checkpoint_cost, 0),
    ("Memory: the estimate (`sac_jax.memory`) within 25 % of the measured peak, 1 to 64 seeds, "
     "10^4 to 10^7 slots (CPU: peak RSS; GPU: peak device bytes)", "Scale", _target_memory, 0),
    ("Memory: peak bytes per replay slot ≤ 1.15x the slot's own data, CPU and GPU", "Scale",
     _target_memory_per_slot, 0),
    ("CPU: `scripts/train.py --preset CartpoleBalance` delivers a policy scoring ≥ 900 (of 1000) "
     "in the Playground task, ≤ 3 min from a cold start, 2 cores", "MuJoCo Playground",
     _target_playground_cpu, 0),
    ("GPU: on each pendulum-family Playground task, ours reaches Playground SAC's final return in "
     "≤ 1/3 of its wall time", "MuJoCo Playground", _target_playground_peer, 0),
    ("GPU: on each pendulum-family Playground task, 16 seeds vmapped reach it in ≤ 2x one "
     "seed's time", "MuJoCo Playground", _target_playground_peer, 1),
    ("`scripts/train.py` run time ≤ 1.15x the jitted `make_train` of the same config, "
     "evaluating every 500 steps (rejax's Pendulum-v1 SAC), CPU and GPU", "rejax",
     lambda: _target_rejax("script_over_program", 1.15, False), 0),
    ("Evaluation ≤ 10 % of a run that evaluates every 500 steps (rejax's Pendulum-v1 SAC, "
     "our program)", "rejax", _target_evaluation_share, 0),
    ("End to end through `scripts/train.py`: ≥ 2x rejax, each from its process's start to its "
     "trained result with JAX's compilation cache warm, 1 and 16 seeds on 2 CPU cores, 1 and "
     "256 on one GPU", "rejax",
     lambda: _target_rejax("rejax_warm_over_script_to_result_warm", 2.0, True), 0),
    ("`fast` preset cold compile (`scripts/train.py`, empty cache) ≤ 10 s, on 2 CPU cores and "
     "on one H100", "Delivered policy", _target_cold_compile, 0),
    ("Playground adapter overhead ≤ 5 % of the raw task step (pendulum family, CPU and GPU)",
     "MuJoCo Playground", _target_playground_adapter, 0),
    ("2 GPUs, data parallel: ≥ 1.8x one GPU on a large configuration (≥ 262,144 envs)",
     "Scale", _target_parallel, 0),
    ("GPU: a sweep of 64 settings x 4 seeds of `fast` in one program, wall time ≤ 3x one "
     "seed's run", "Scale", lambda: _target_sweep("gpu", 3.0), 0),
    ("CPU: 8 settings x 2 seeds in one program, reported against 16 separate runs", "Scale",
     lambda: _target_sweep("cpu", None), 0),
]


def targets() -> str:
    """Each target, its latest figure and whether it is met, computed from the results."""
    rows = []
    for target, section, figures, index in TARGETS:
        found = figures()
        if found is None:
            rows.append([target, "_not measured yet_", "-", section, "-"])
            continue
        names, results = found
        figure, met = results[index]
        dates = sorted({_date(_load(n)) for n in names})
        status = {True: "**met**", False: "not met", None: "not all measured"}.get(met, met)
        rows.append([target, figure, status, section,
                     ", ".join(f"`{n}.json`" for n in names) + f" ({', '.join(dates)})"])
    return _table(["target", "latest figure", "status", "section", "results (date)"], rows)


TABLES: Dict[str, Callable[[], str]] = {
    "targets": targets, "delivered-cpu": delivered_cpu, "delivered-gpu": delivered_gpu,
    "presets": presets, "env": env,
    "updates-cpu": updates_cpu, "seed-scaling": seed_scaling,
    "brax": brax, "torch": torch_loop, "progress": progress, "parallel": parallel,
    "memory": memory, "sweep": sweep, "playground": playground,
    "playground-peer": playground_peer, "rejax": rejax, "compile-options": compile_options}


def render(text: str) -> str:
    """`text` (a page of `DOCS`) with every generated table written anew from the results."""
    def table(match):
        name = match.group(2)
        if name not in TABLES:
            raise SystemExit(f"no generated table named {name!r}")
        return match.group(1) + TABLES[name]() + match.group(4)

    return BLOCK.sub(table, text)


def main() -> int:
    global RESULTS
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true",
                        help="exit 1 if a page's generated tables differ from the results")
    parser.add_argument("--results", default=RESULTS,
                        help="the folder of results files (default benchmarks/results)")
    parser.add_argument("--print", action="store_true",
                        help="print the rendered pages instead of writing them")
    args = parser.parse_args()
    RESULTS = args.results
    differ = False
    for doc in DOCS:
        with open(doc) as f:
            text = f.read()
        new = render(text)
        if args.print:
            sys.stdout.write(new)
        elif args.check:
            if new != text:
                print(f"{os.path.relpath(doc, ROOT)} differs from benchmarks/results: run "
                      "python -m benchmarks.tables", file=sys.stderr)
                differ = True
        else:
            with open(doc, "w") as f:
                f.write(new)
            print(f"wrote {doc}: {len(BLOCK.findall(new))} generated tables")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
