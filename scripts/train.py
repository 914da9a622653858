"""Train SAC: one compiled program for the whole run, all seeds vmapped in it.

    python scripts/train.py                                  # the `fast` preset, 1 seed
    python scripts/train.py --preset cleanrl --seeds 1
    python scripts/train.py --preset pendulum --total-steps 20000 --out runs/pendulum
    python scripts/train.py --help                           # every SACConfig field is a flag

Prints one progress line per evaluation point (mean over seeds), then a summary. With --out it
writes config.json, metrics.csv (one row per evaluation and seed) and summary.json there.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import sac_jax  # noqa: E402
from sac_jax.config import field_docs  # noqa: E402
from sac_jax.presets import DEFAULT_PRESET, PRESETS  # noqa: E402
from sac_jax.run import RunResult, run_training, write_run_dir  # noqa: E402


def _parse_field(hint: str):
    """argparse (type, metavar) for a SACConfig field annotation (a string)."""
    if hint.startswith("Tuple[int"):
        return (lambda s: tuple(int(x) for x in s.replace(",", " ").split())), "N,N,..."
    if hint.startswith("Tuple[str"):
        return (lambda s: tuple(x for x in s.replace(",", " ").split())), "NAME,NAME,..."
    if hint == "Optional[str]":
        return (lambda s: None if s.lower() == "none" else s), "NAME|none"
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
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--preset", default=DEFAULT_PRESET, choices=sorted(PRESETS),
                        help=f"base configuration (default {DEFAULT_PRESET})")
    parser.add_argument("--seeds", type=int, default=1,
                        help="seeds trained at once in one vmapped program (default 1)")
    parser.add_argument("--seed", type=int, default=0, help="PRNG seed of the first run")
    parser.add_argument("--out", default=None, help="run directory to write (must not exist)")
    parser.add_argument("--no-cache", action="store_true",
                        help="turn JAX's persistent compilation cache off")
    parser.add_argument("--cache-dir", default=None,
                        help="compilation cache directory (default ~/.cache/sac-jax/jax)")
    group = parser.add_argument_group("SACConfig fields (each overrides the preset)")
    docs = field_docs()
    for field in dataclasses.fields(sac_jax.SACConfig):
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


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        overrides = {f.name: getattr(args, f.name) for f in dataclasses.fields(sac_jax.SACConfig)
                     if getattr(args, f.name) is not None}
        config = PRESETS[args.preset].replace(**overrides)
        if args.seeds < 1:
            raise ValueError(f"--seeds={args.seeds}: must be at least 1")
        if args.out and os.path.exists(args.out):
            raise ValueError(f"--out={args.out}: already exists; choose a new run directory")
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    if not args.no_cache:
        sac_jax.enable_compilation_cache(args.cache_dir)
    print(f"preset {args.preset} on {config.env}: {args.seeds} seed(s), {config.total_steps} "
          f"steps each, {config.num_envs} envs, {config.updates_per_step} updates/iteration",
          flush=True)

    def on_point(step, point, elapsed):
        print(_progress_line(step, point, args.seeds, elapsed), flush=True)

    result: RunResult = run_training(config, seeds=args.seeds, seed=args.seed, on_point=on_point)
    s = result.summary
    returns, solved = s["eval_return"], s["solved_at_step"]
    if len(returns) <= 8:
        outcome = (f"final eval return per seed {[round(r, 1) for r in returns]}; "
                   f"solved at step {solved}")
    else:
        threshold = s["solved_threshold"]
        reached = sum(r >= threshold for r in returns) if threshold is not None else "-"
        outcome = (f"final eval return mean {sum(returns) / len(returns):.1f} (min "
                   f"{min(returns):.1f}, max {max(returns):.1f}); {reached}/{len(returns)} seeds "
                   f"at >= {threshold} at the end, {sum(x is not None for x in solved)} solved "
                   "at some evaluation")
    print(f"compile {s['compile_s']:.1f} s, run {s['run_s']:.1f} s; {outcome} "
          f"(mean over seeds solved after {s['solved_wall_s']} s of training)", flush=True)
    if args.out:
        write_run_dir(args.out, config, args.preset, result)
        print(f"wrote {args.out}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
