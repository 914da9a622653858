"""Train SAC: one compiled program for the whole run, all seeds vmapped in it.

    python scripts/train.py                                  # the `fast` preset, 1 seed
    python scripts/train.py --preset cleanrl --seeds 4
    python scripts/train.py --preset pendulum --total-steps 20000 --out runs/pendulum
    python scripts/train.py --resume runs/pendulum           # continue a stopped run
    python scripts/train.py --help                           # every SACConfig field is a flag

Prints one progress line per evaluation point (mean over seeds) and writes the run directory
(default runs/<preset>-<env>-<time>): config.json, run.json, checkpoint.msgpack (at every
evaluation), tensorboard/ (live), and at the end metrics.csv, summary.json and curves.png.
Ctrl-C or SIGTERM stops after the current chunk of the compiled loop, saves a checkpoint and the
summary, and exits with 130 or 143; `--resume` continues it to the same result as an
uninterrupted run. A non-finite parameter stops the run (exit 1) and keeps the last good
checkpoint. Bad input ends with one line on stderr and exit 2, before anything is written.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import signal
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import sac_jax  # noqa: E402
from sac_jax.config import field_docs  # noqa: E402
from sac_jax.presets import DEFAULT_PRESET, PRESETS  # noqa: E402
from sac_jax import run_dir  # noqa: E402
from sac_jax.run import FINISHED, INTERRUPTED, RunResult, run_training  # noqa: E402
from scripts._cli import Parser  # noqa: E402

EXIT_CODES = {signal.SIGINT: 130, signal.SIGTERM: 143}


def _flag_fields():
    """The SACConfig fields that are flags: all but `data_parallel_axis`, which
    `sac_jax.parallel` sets on each device's share of a data-parallel run."""
    return [f for f in dataclasses.fields(sac_jax.SACConfig) if f.name != "data_parallel_axis"]


def _parse_field(hint: str):
    """argparse (type, metavar) for a SACConfig field annotation (a string)."""
    if hint.startswith("Tuple[int"):
        return (lambda s: tuple(int(x) for x in s.replace(",", " ").split())), "N,N,..."
    if hint.startswith("Tuple[str"):
        return (lambda s: tuple(x for x in s.replace(",", " ").split())), "NAME,NAME,..."
    if hint.startswith("Optional"):
        return (lambda s: None if s.lower() == "none" else float(s)), "FLOAT|none"
    if hint == "bool":
        def boolean(s):
            if s.lower() not in ("true", "false"):
                raise argparse.ArgumentTypeError(f"expected true or false, got {s!r}")
            return s.lower() == "true"
        return boolean, "true|false"
    return {"int": int, "float": float, "str": str}[hint], hint.upper()


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--preset", default=None, choices=sorted(PRESETS),
                        help=f"base configuration (default {DEFAULT_PRESET})")
    parser.add_argument("--seeds", type=int, default=None,
                        help="seeds trained at once in one vmapped program (default 1)")
    parser.add_argument("--seed", type=int, default=None, help="PRNG seed of the first run (0)")
    parser.add_argument("--out", default=None,
                        help="run directory to create (must not exist; default "
                             "runs/<preset>-<env>-<time>)")
    parser.add_argument("--resume", default=None, metavar="RUN_DIR",
                        help="continue the run saved in RUN_DIR from its checkpoint (its own "
                             "configuration; no other run or config flags)")
    parser.add_argument("--no-cache", action="store_true",
                        help="turn JAX's persistent compilation cache off")
    parser.add_argument("--cache-dir", default=None,
                        help="compilation cache directory (default ~/.cache/sac-jax/jax)")
    group = parser.add_argument_group("SACConfig fields (each overrides the preset)")
    docs = field_docs()
    for field in _flag_fields():
        kind, metavar = _parse_field(str(field.type))
        group.add_argument("--" + field.name.replace("_", "-"), dest=field.name, type=kind,
                           metavar=metavar, default=None, help=docs.get(field.name, ""))
    return parser


def _progress_line(step: int, point: dict, seeds: int, elapsed: float) -> str:
    """One line per evaluation point; a value that is not defined at this point (e.g. no
    training episode ended since the last evaluation) shows as "-"."""
    def number(name, spec):
        value = point[name]
        return format(value, spec) if math.isfinite(value) else "-".rjust(len(format(0.0, spec)))

    return (f"step {step:>8d} | eval {number('eval_return', '9.1f')} | train "
            f"{number('train_return', '9.1f')} | alpha {number('alpha', '.3f')} | critic "
            f"{number('critic_loss', '.3g')} | actor {number('actor_loss', '.3g')} | "
            f"{step * seeds / max(elapsed, 1e-9):8.0f} steps/s | {elapsed:6.1f} s")


def _new_run(args):
    """(config, run info, run directory) of a fresh run; the directory is created last, once
    every input is known to be good. ValueError on bad input."""
    preset = args.preset or DEFAULT_PRESET
    overrides = {f.name: getattr(args, f.name) for f in _flag_fields()
                 if getattr(args, f.name) is not None}
    config = PRESETS[preset].replace(**overrides)
    info = {"preset": preset, "seeds": 1 if args.seeds is None else args.seeds,
            "seed": args.seed or 0}
    if info["seeds"] < 1:
        raise ValueError(f"--seeds={info['seeds']}: must be at least 1")
    out = args.out or os.path.join(
        "runs", f"{preset}-{config.env}-{time.strftime('%Y%m%d-%H%M%S')}")
    run_dir.create(out, config, **info)
    return config, info, out


def _resumed_run(args):
    """(config, run info, run directory, (state, position)) of the run in `--resume`."""
    given = [a for a, v in vars(args).items()
             if v is not None and a not in ("resume", "no_cache", "cache_dir")]
    if given:
        flag = "--" + given[0].replace("_", "-")
        raise ValueError(f"--resume={args.resume}: a resumed run keeps its own configuration; "
                         f"remove {flag}")
    config, info, state, position = run_dir.load_checkpoint(args.resume)
    from sac_jax.train import make_train_parts
    if position["chunks_done"] >= make_train_parts(config).num_chunks:
        raise ValueError(f"--resume={args.resume}: this run already finished")
    return config, info, args.resume, (state, position)


class _StopRequest:
    """Signal handler: the first SIGINT/SIGTERM asks the run to stop at the next chunk boundary
    (after saving); a second one stops at once."""

    def __init__(self):
        self.signal = None

    def __call__(self, signum, frame):
        if self.signal is not None:
            raise KeyboardInterrupt
        self.signal = signum
        print(f"{signal.Signals(signum).name}: stopping after the current chunk; saving a "
              "checkpoint (again to stop at once)", file=sys.stderr, flush=True)


def _outcome(summary: dict) -> str:
    returns, solved = summary["eval_return"], summary["solved_at_step"]
    if len(returns) <= 8:
        return (f"final eval return per seed {[round(r, 1) for r in returns]}; "
                f"solved at step {solved}")
    threshold = summary["solved_threshold"]
    reached = sum(r >= threshold for r in returns) if threshold is not None else "-"
    return (f"final eval return mean {sum(returns) / len(returns):.1f} (min "
            f"{min(returns):.1f}, max {max(returns):.1f}); {reached}/{len(returns)} seeds at >= "
            f"{threshold} at the end, {sum(x is not None for x in solved)} solved at some "
            "evaluation")


def _write_results(out: str, config, info: dict, result: RunResult) -> None:
    run_dir.write_metrics(out, result.metrics, result.points)
    run_dir.write_summary(out, dict(result.summary, preset=info["preset"]))
    if result.points:
        run_dir.write_curves(out, result.metrics, result.points,
                             f"{config.env}, preset {info['preset']}",
                             result.summary["solved_threshold"])


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        if args.resume:
            config, info, out, resume = _resumed_run(args)
        else:
            (config, info, out), resume = _new_run(args), None
    except ValueError as error:  # also RunDirError and CheckpointError
        print(f"error: {error}", file=sys.stderr)
        return 2
    if not args.no_cache:
        sac_jax.enable_compilation_cache(args.cache_dir)
    seeds = info["seeds"]
    print(f"{'resuming' if resume else 'preset'} {info['preset']} on {config.env}: {seeds} "
          f"seed(s), {config.total_steps} steps each, {config.num_envs} envs, "
          f"{config.updates_per_step} updates/iteration -> {out}", flush=True)
    tensorboard = run_dir.TensorBoard(out)

    def on_point(step, means, eval_returns, elapsed):
        print(_progress_line(step, means, seeds, elapsed), flush=True)
        tensorboard.add_point(step, means, eval_returns)

    stop = _StopRequest()
    previous = {s: signal.signal(s, stop) for s in EXIT_CODES}
    try:
        result = run_training(
            config, seeds=seeds, seed=info["seed"], resume=resume, on_point=on_point,
            on_checkpoint=lambda state, position: run_dir.save_checkpoint(out, state, position),
            should_stop=lambda: stop.signal is not None)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        tensorboard.close()
    _write_results(out, config, info, result)
    s = result.summary
    if result.status == FINISHED:
        print(f"compile {s['compile_s']:.1f} s, run {s['run_s']:.1f} s; {_outcome(s)} (mean over "
              f"seeds solved after {s['solved_wall_s']} s of training); wrote {out}", flush=True)
        return 0
    if result.status == INTERRUPTED:
        print(f"{result.message}; checkpoint saved: continue with --resume {out}",
              file=sys.stderr, flush=True)
        return EXIT_CODES[stop.signal]
    kept = (f"last good checkpoint kept in {out}" if os.path.exists(
        os.path.join(out, run_dir.CHECKPOINT)) else "no evaluation point was reached before it")
    print(f"error: {result.message}; {kept}", file=sys.stderr, flush=True)
    return 1


if __name__ == "__main__":
    sys.exit(main())
