"""Sweep SAC hyperparameters: a grid of settings x seeds, in as few compiled programs as the
settings allow.

    python scripts/sweep.py --preset pendulum --total-steps 3000 --eval-every 1000 --seeds 2 \\
        --set actor_lr=1e-3,3e-4 --out runs/sweep            # 2 settings x 2 seeds, one program
    python scripts/sweep.py --set actor_lr=1e-3,3e-3 --set tau=0.005,0.02 --seeds 4
    python scripts/sweep.py --set batch_size=128,256 --set critic_lr=1e-3,3e-3   # 2 programs
    python scripts/sweep.py --resume runs/sweep               # continue a stopped sweep

`--set FIELD=V1,V2,...` (repeatable) sweeps a numeric SACConfig field; the settings are the grid
over every `--set`, each trained on the same `--seeds` keys, and every other flag of
scripts/train.py sets the base configuration. The fields that change no shape are traced
values of one vmapped program (they are in `sac_jax.hyperparams.NAMES`: gamma, tau,
reward_scale, loss_coef, alpha_init, log_alpha_init, target_entropy and the learning rates);
every combination of the other fields (batch_size, num_envs, buffer_size, ...) is a program of
its own, compiled once and run after the previous one. A setting whose state turns non-finite
is reported and the others train on.

Writes the sweep directory (default runs/sweep-<preset>-<time>): sweep.json (what was asked),
programs/<i>/ (a run directory per program, as scripts/train.py writes; `sac_jax.load_policy`
loads its runs, setting-major), results.csv (one row per setting and seed: its values, the
delivered actor's confirmed return, the step from which it stayed solved, the last evaluation
and the last period's losses), sweep.png (delivered return against each swept field, and each
setting's learning curve), and prints the best setting (highest mean delivered return over its
seeds, then earliest mean solved step) as a ready scripts/train.py command line. With
`--track`, each program directory is also a W&B run of its own (id in its wandb.json), as
scripts/train.py's.
Ctrl-C or SIGTERM stops after the current chunk, saves, and exits with 130 or 143; `--resume`
continues the sweep. Bad input (an unknown or non-numeric field, an empty or invalid value, a
program that cannot fit in memory) ends with one line on stderr and exit 2, nothing written.
"""

from __future__ import annotations

import time

STARTED = time.perf_counter()  # process start, for the times to a solved policy

import csv  # noqa: E402
import dataclasses  # noqa: E402
import io  # noqa: E402
import itertools  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import os  # noqa: E402
import shutil  # noqa: E402
import signal  # noqa: E402
import sys  # noqa: E402
import typing  # noqa: E402
from typing import Annotated, Dict, List, Literal, Optional, Sequence, Tuple  # noqa: E402

import tyro  # noqa: E402

import sac_jax  # noqa: E402
from sac_jax import (hyperparams, memory, parallel, plots, run_checkpoint,  # noqa: E402
                     run_dir, tracking)
from sac_jax.cli import (EXIT_CODES, PresetName, RunFailed, StopRequest,  # noqa: E402
                         after_failure, check_resume_flags, device_split, fail,
                         parse_with_preset, positive, prng_seed, run_main, train_in_dir)
from sac_jax.config import SACConfig  # noqa: E402
from sac_jax.presets import DEFAULT_PRESET, PRESETS  # noqa: E402
from sac_jax.run import INTERRUPTED, DeviceBusy  # noqa: E402

LOSSES = ("critic_loss", "actor_loss", "alpha_loss", "value_loss", "alpha")


@dataclasses.dataclass(frozen=True)
class SweepArgs:
    """Sweep SAC hyperparameters: a grid of settings x seeds in as few compiled programs as the
    settings allow."""

    preset: PresetName = DEFAULT_PRESET
    """Base configuration; each SACConfig flag below overrides one of its fields."""
    sets: Annotated[Tuple[str, ...], tyro.conf.arg(name="set"), tyro.conf.UseAppendAction] = ()
    """FIELD=V1,V2,... : values of a numeric SACConfig field to sweep (repeat for a grid)."""
    seeds: int = 1
    """Seeds per setting (the same keys for every setting)."""
    seed: int = 0
    """PRNG seed; each seed's key is split from it."""
    out: Optional[str] = None
    """Sweep directory to create (must not exist); default runs/sweep-<preset>-<time>."""
    resume: Optional[str] = None
    """Continue the sweep saved in this directory (no other sweep or config flags)."""
    cache: bool = True
    """JAX's persistent compilation cache."""
    cache_dir: Optional[str] = None
    """Compilation cache directory (default $JAX_COMPILATION_CACHE_DIR or ~/.cache/sac-jax/jax)."""
    memory_check: bool = True
    """Refuse, before anything is written or compiled, a program that cannot fit in memory."""
    track: bool = False
    """Also log to Weights & Biases (needs `pip install -e ".[track]"`): one W&B run per
    program directory (named <name>-program<i>), as scripts/train.py logs a run."""
    wandb_project: str = "sac-jax"
    """W&B project (with --track)."""
    wandb_entity: Optional[str] = None
    """W&B entity, a user or team (with --track; default: W&B's default entity)."""
    wandb_name: Optional[str] = None
    """Prefix of the W&B run names (with --track; default: the sweep directory's name)."""
    wandb_mode: Optional[Literal["online", "offline"]] = None
    """W&B mode (with --track; default $WANDB_MODE, else online)."""
    config: Annotated[SACConfig, tyro.conf.OmitArgPrefixes] = PRESETS[DEFAULT_PRESET]

    def __post_init__(self):
        positive("seeds", self.seeds)
        prng_seed("seed", self.seed)


@dataclasses.dataclass(frozen=True)
class Program:
    """One compiled program of a sweep: its config (the shape-changing values applied), the
    traced `settings` {name: values} it trains (None for one setting), and which settings of
    the grid (indices) it holds, in order."""

    config: SACConfig
    settings: Optional[Dict[str, List[float]]]
    indices: Tuple[int, ...]


def _numeric_fields() -> Dict[str, type]:
    """SACConfig's numeric fields (int or float, possibly Optional) and their types."""
    hints = typing.get_type_hints(SACConfig, include_extras=False)
    fields = {}
    for name, hint in hints.items():
        kinds = [t for t in typing.get_args(hint) if t is not type(None)] or [hint]
        if len(kinds) == 1 and kinds[0] in (int, float):
            fields[name] = kinds[0]
    return fields


def parse_sets(sets: Sequence[str]) -> Dict[str, List]:
    """{field: values} from `--set FIELD=V1,V2,...` flags, in the order given. ValueError (one
    line naming the flag) for an unknown or non-numeric field, a repeated field, an empty list,
    a value that is not a number of the field's type or one given twice."""
    numeric, grid = _numeric_fields(), {}
    known = {f.name for f in dataclasses.fields(SACConfig)}
    for text in sets:
        name, equals, values = text.partition("=")
        name = name.strip().replace("-", "_")
        if not equals:
            raise ValueError(f"--set {text!r}: expected FIELD=V1,V2,...")
        if name not in known:
            raise ValueError(f"--set {name}: SACConfig has no such field")
        if name not in numeric:
            raise ValueError(f"--set {name}: not a numeric hyperparameter (sweep only int or "
                             "float fields; set the others with their own flag)")
        if name in grid:
            raise ValueError(f"--set {name}: given twice; list all its values in one --set")
        items = [v.strip() for v in values.split(",") if v.strip()]
        if not items:
            raise ValueError(f"--set {name}: no values")
        kind, parsed = numeric[name], []
        for item in items:
            try:
                parsed.append(int(item) if kind is int else float(item))
            except ValueError:
                wanted = "an integer" if kind is int else "a number"
                raise ValueError(f"--set {name}={item!r}: not {wanted}") from None
        repeated = sorted({v for v in parsed if parsed.count(v) > 1})
        if repeated:  # two settings of one value would be one run reported twice
            raise ValueError(f"--set {name}: {', '.join(map(str, repeated))} given more than "
                             "once")
        grid[name] = parsed
    return grid


def plan(base: SACConfig, grid: Dict[str, List]) -> Tuple[List[Dict], List[Program]]:
    """(settings: the grid's points in order, each {field: value}; programs). Settings that
    differ only in `hyperparams.NAMES` share a program. Every setting's config is validated
    (ValueError naming the field and the setting)."""
    points = [dict(zip(grid, values)) for values in itertools.product(*grid.values())] or [{}]
    groups: Dict[Tuple, List[int]] = {}
    for i, point in enumerate(points):
        try:
            base.replace(**point)
        except ValueError as error:
            raise ValueError(f"--set setting {_describe(point)}: {error}") from None
        shape = tuple((k, v) for k, v in point.items() if k not in hyperparams.NAMES)
        groups.setdefault(shape, []).append(i)
    programs = []
    for shape, indices in groups.items():
        traced = [k for k in grid if k in hyperparams.NAMES]
        settings = ({k: [points[i][k] for i in indices] for k in traced}
                    if traced and len(indices) > 1 else None)
        config = base.replace(**dict(shape))
        if settings is None and traced:
            config = config.replace(**{k: points[indices[0]][k] for k in traced})
        programs.append(Program(config, settings, tuple(indices)))
    return points, programs


def _describe(point: Dict) -> str:
    return ", ".join(f"{k}={v:g}" for k, v in point.items()) or "(base)"


def train_command(preset: str, config: SACConfig) -> str:
    """The scripts/train.py command line that trains `config`: `--preset` and a flag for each
    field that differs from the preset's."""
    flags = []
    for field in dataclasses.fields(SACConfig):
        value, default = getattr(config, field.name), getattr(PRESETS[preset], field.name)
        if value == default:
            continue
        flag = "--" + field.name.replace("_", "-")
        if isinstance(value, bool):
            flags.append(flag if value else f"--no-{field.name.replace('_', '-')}")
        elif isinstance(value, tuple):
            flags.append(" ".join([flag, *map(str, value)]))
        else:
            flags.append(f"{flag} {value!r}" if isinstance(value, float) else f"{flag} {value}")
    return " ".join(["python scripts/train.py --preset", preset, *flags])


def parse_args(argv: Optional[Sequence[str]] = None) -> SweepArgs:
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parse_with_preset(SweepArgs, argv, __doc__)
    if args.resume is not None:
        check_resume_flags(argv, args.resume, "sweep")
    elif not args.sets:
        raise ValueError("--set: give at least one FIELD=V1,V2,... to sweep")
    return args


def _program_dir(out: str, i: int) -> str:
    return os.path.join(out, "programs", str(i))


def _read_sweep(out: str) -> dict:
    try:
        with open(os.path.join(out, "sweep.json")) as f:
            sweep = json.load(f)
        sweep["config"] = run_dir.stored_config(sweep["config"])
        return sweep
    except (OSError, ValueError, TypeError, KeyError) as error:
        raise run_dir.RunDirError(
            f"--resume={out}: not a readable sweep directory ({error})") from None


def _memory_lines(args: SweepArgs, programs: List[Program], seeds: int) -> List[str]:
    if not args.memory_check:
        return ["memory not checked (--no-memory-check)"] * len(programs)
    return [memory.check(p.config, seeds * len(p.indices)) for p in programs]


def _run_program(i: int, program: Program, sweep: dict, out: str, stop: StopRequest,
                 fits: str, count: int):
    """Trains program i (resuming its checkpoint if it has one); its `RunResult`, or None if it
    had already finished. `RunFailed` names the program and what the sweep leaves."""
    path = _program_dir(out, i)
    seeds, runs = sweep["seeds"], sweep["seeds"] * len(program.indices)
    resume = None
    if run_dir.results_written(path):
        return None
    if run_checkpoint.saved_steps(path):
        _, _, state, position = run_checkpoint.load_checkpoint(path)
        resume = (state, position)
    else:  # never checkpointed: start it afresh
        shutil.rmtree(path, ignore_errors=True)
        run_dir.create(path, program.config, sweep["preset"], seeds, sweep["seed"],
                       program.settings)
        if sweep.get("track"):
            track = sweep["track"]
            name = f"{track['name'] or os.path.basename(os.path.abspath(out))}-program{i}"
            tracking.save_settings(path, tracking.settings(
                track["project"], track["entity"], name, track["mode"]))
    swept = (", ".join(f"{k}={_span(v)}" for k, v in program.settings.items())
             if program.settings else _describe({k: v for k, v in
                                                 sweep["points"][program.indices[0]].items()}))
    print(f"program {i + 1}/{count} ({'resuming, ' if resume else ''}{swept}): "
          f"{len(program.indices)} setting(s) x {seeds} seed(s) = {runs} runs"
          f"{device_split(runs)}, {program.config.run_steps} steps each; {fits} -> {path}",
          flush=True)
    try:
        return train_in_dir(
            path, program.config, sweep["preset"], seeds=seeds, seed=sweep["seed"],
            settings=program.settings, resume=resume, stop=stop, runs=runs, started=STARTED,
            tracked=dict(dataclasses.asdict(program.config), preset=sweep["preset"],
                         seeds=seeds, seed=sweep["seed"], settings=program.settings),
            stop_on_non_finite=False)[0]
    except RunFailed as error:  # the sweep, not the program, is what a user resumes
        raise RunFailed(f"program {i + 1}: {error}; "
                        f"{after_failure(path, resume is None, out)}") from None


def _span(values) -> str:
    return "{" + ",".join(f"{v:g}" for v in values) + "}"


def _rows(sweep: dict, programs: List[Program], out: str) -> List[dict]:
    """One row per (setting, seed), from the programs' summary.json and metrics.csv."""
    rows = []
    for i, program in enumerate(programs):
        path = _program_dir(out, i)
        with open(os.path.join(path, "summary.json")) as f:
            summary = json.load(f)
        last = {}
        with open(os.path.join(path, "metrics.csv")) as f:
            for record in csv.DictReader(f):
                last[int(record["seed"])] = record  # the last evaluation point of each run
        for position, index in enumerate(program.indices):
            for seed in range(sweep["seeds"]):
                run = hyperparams.run_index(position, seed, sweep["seeds"])
                record = last.get(run, {})
                rows.append({
                    "setting": index, **sweep["points"][index], "seed": seed, "program": i,
                    "delivered_return": summary["delivered_return"][run],
                    "solved_at_step": summary["solved_at_step"][run],
                    "solved_wall_s": summary["solved_wall_s"][run],
                    "eval_return": summary["eval_return"][run],
                    "env_steps": int(float(record.get("env_steps", 0))),
                    **{name: float(record[name]) if name in record else math.nan
                       for name in LOSSES},
                    "non_finite_at_step": summary["non_finite_at_step"][run]})
    return sorted(rows, key=lambda r: (r["setting"], r["seed"]))


def _write_csv(out: str, rows: List[dict]) -> None:
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: "" if v is None else v for k, v in row.items()})
    run_dir.write_file(os.path.join(out, "results.csv"), text.getvalue().encode())


def best_setting(rows: List[dict], count: int) -> Tuple[int, float]:
    """(setting, its mean delivered return): the highest mean delivered return over its seeds,
    ties to the earliest mean solved step (never solved counting as infinitely late). A seed
    that delivered no actor (a non-finite return: its state went non-finite before its first
    point) counts as -inf, so its setting ranks below every setting whose seeds all delivered."""
    def score(setting):
        mine = [r for r in rows if r["setting"] == setting]
        returns = [r["delivered_return"] for r in mine]
        mean = (sum(returns) / len(returns) if returns and all(map(math.isfinite, returns))
                else -math.inf)
        steps = [math.inf if r["solved_at_step"] is None else r["solved_at_step"] for r in mine]
        return mean, -sum(steps) / len(steps)

    best = max(range(count), key=score)
    return best, score(best)[0]


def _write_plot(out: str, sweep: dict, rows: List[dict], programs: List[Program]) -> None:
    """sweep.png: per swept field, each run's delivered return (dots) and the mean over seeds
    and the other fields' values (line) against the field's values; then each setting's mean
    evaluation return of its last actor against environment steps."""
    import numpy as np

    names = list(sweep["grid"])
    fig = plots.figure(figsize=(4.2 * (len(names) + 1), 3.6), dpi=100)
    axes = fig.subplots(1, len(names) + 1, squeeze=False)
    for ax, name in zip(axes[0], names):
        values = sorted(set(sweep["grid"][name]))
        x = [r[name] for r in rows]
        y = [r["delivered_return"] for r in rows]
        ax.scatter(x, y, s=12, alpha=0.5, label="one run")
        ax.plot(values, [np.nanmean([r["delivered_return"] for r in rows if r[name] == v])
                         for v in values], marker="o", label="mean")
        if min(values) > 0 and max(values) / min(values) >= 10:
            ax.set_xscale("log")
        ax.set(xlabel=name, ylabel="delivered return")
        ax.grid(alpha=0.3)
    axes[0][0].legend(loc="best")
    fig.subplots_adjust(wspace=0.35)
    ax = axes[0][-1]
    for i, program in enumerate(programs):
        with open(os.path.join(_program_dir(out, i), "metrics.csv")) as f:
            records = list(csv.DictReader(f))
        for position, index in enumerate(program.indices):
            mine = [r for r in records
                    if hyperparams.setting_of(int(r["seed"]), sweep["seeds"]) == position]
            steps = sorted({int(float(r["env_steps"])) for r in mine})
            curve = [np.nanmean([float(r["eval_return"]) for r in mine
                                 if int(float(r["env_steps"])) == s]) for s in steps]
            ax.plot(steps, curve, label=_describe(sweep["points"][index]))
    ax.set(xlabel="environment steps", ylabel="evaluation return (mean over seeds)")
    ax.grid(alpha=0.3)
    if len(sweep["points"]) <= 12:
        ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=7)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", bbox_inches="tight")
    run_dir.write_file(os.path.join(out, "sweep.png"), buffer.getvalue())


def main(argv=None) -> int:
    # first, before JAX starts (here or from `sac-jax`): a CPU's seeds split over its cores,
    # and XLA's CPU kernels in sequence (`compilation_cache.sequential_cpu_scheduler`)
    parallel.cpu_device_per_core()
    sac_jax.compilation_cache.sequential_cpu_scheduler()
    try:
        args = parse_args(argv)
        # before the memory checks, whose state shapes the cache keeps (run_dir.state_template)
        sac_jax.compilation_cache.use_compilation_cache(args.cache, args.cache_dir)
        if args.resume:
            out, sweep = args.resume, _read_sweep(args.resume)
            points, programs = plan(sweep["config"], sweep["grid"])
        else:
            grid = parse_sets(args.sets)
            points, programs = plan(args.config, grid)
            out = args.out or os.path.join(
                "runs", f"sweep-{args.preset}-{time.strftime('%Y%m%d-%H%M%S')}")
            run_dir.check_new(out)  # before the memory checks' work
            sweep = {"preset": args.preset, "seeds": args.seeds, "seed": args.seed,
                     "grid": grid, "config": args.config}
            if args.track:
                sweep["track"] = {"project": args.wandb_project, "entity": args.wandb_entity,
                                  "name": args.wandb_name, "mode": args.wandb_mode}
        if sweep.get("track"):
            tracking.check_available()
        fits = _memory_lines(args, programs, sweep["seeds"])
        if not args.resume:
            run_dir.create_directory(out, {"sweep.json": dict(
                sweep, config=dataclasses.asdict(args.config), points=points)})
    except ValueError as error:  # also UsageError, RunDirError, CheckpointError, MemoryRefused
        return fail(error, 2)
    sweep["points"] = points
    print(f"sweep of {len(points)} setting(s) x {sweep['seeds']} seed(s) in {len(programs)} "
          f"program(s) ({sweep['preset']} on {sweep['config'].env}) -> {out}", flush=True)
    stop = StopRequest()
    previous = {s: signal.signal(s, stop) for s in EXIT_CODES}
    try:
        for i, program in enumerate(programs):
            result = _run_program(i, program, sweep, out, stop, fits[i], len(programs))
            if result is not None and result.status == INTERRUPTED:
                print(f"program {i + 1}: {result.message}; checkpoint saved: continue with "
                      f"--resume {out}", file=sys.stderr, flush=True)
                return EXIT_CODES[stop.signal]
    except (KeyboardInterrupt, DeviceBusy) as error:  # every file is whole or absent
        stop.leave_now(error, f"continue with --resume {out}")
    except RunFailed as error:  # a checkpoint that cannot be written, W&B, memory exhausted
        print(f"error: {error}", file=sys.stderr, flush=True)
        return 1
    except ValueError as error:  # a program's checkpoint that cannot be read back
        return fail(error, 2)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    rows = _rows(sweep, programs, out)
    _write_csv(out, rows)
    _write_plot(out, sweep, rows, programs)
    best, mean = best_setting(rows, len(points))
    point = points[best]
    diverged = sorted({r["setting"] for r in rows if r["non_finite_at_step"] is not None})
    if diverged:
        print(f"settings {diverged} became non-finite (results.csv: non_finite_at_step); "
              "their delivered actors are the last confirmed before", flush=True)
    print(f"best setting {best} ({_describe(point)}): mean delivered return {mean:.1f} over "
          f"{sweep['seeds']} seed(s); train it with: "
          f"{train_command(sweep['preset'], sweep['config'].replace(**point))}; wrote {out}",
          flush=True)
    return 0


if __name__ == "__main__":
    run_main(main)
