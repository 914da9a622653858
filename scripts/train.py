"""Train SAC: one compiled program for the whole run, all seeds vmapped in it.

    python scripts/train.py                                  # the `fast` preset, 1 seed
    python scripts/train.py --preset cleanrl --seeds 4
    python scripts/train.py --preset pendulum --total-steps 20000 --out runs/pendulum
    python scripts/train.py --resume runs/pendulum           # continue a stopped run
    python scripts/train.py --help                           # every SACConfig field is a flag

Prints one progress line per evaluation point (means over seeds: the last actor's and the
delivered actor's returns; how many seeds' delivered policies are solved, and stopped) and
writes the run directory (default runs/<preset>-<env>-<time>): config.json, run.json,
checkpoints/ (at evaluation points, at most every 5 s, and at the end; the newest two kept),
tensorboard/ (live), and at the end metrics.csv, summary.json and curves.png; with --track,
wandb.json (the W&B run's id) and W&B's files. What the run delivers is each seed's best
confirmed actor (`sac_jax.selection`), which `sac_jax.load_policy` and scripts/evaluate.py load.
Ctrl-C or SIGTERM stops after the current chunk of the compiled loop, saves a checkpoint and the
summary, and exits with 130 or 143 (a second one, or a chunk still running 10 s after the first,
stops at once, keeping the last checkpoint); `--resume` continues it to the same result as an
uninterrupted run (a run killed after its last checkpoint gets its result files). A non-finite
parameter stops the run (exit 1), saving its state with the delivered actors (a resume of it is
refused: it would repeat the same updates). A checkpoint, TensorBoard's records or the result
files that cannot be written (e.g. a full disk), or W&B failing (with --track), stop it with
one line, keeping the last good checkpoint. A damaged checkpoint is refused (exit 2), naming
an intact earlier one to resume from with `--resume-step`. Bad input,
or a run that cannot fit in memory, ends with one line on stderr and exit 2, before anything
is written.
"""

from __future__ import annotations

import gc
import time

STARTED = time.perf_counter()  # process start, for the times to a solved policy
if __name__ == "__main__":
    gc.disable()  # while the modules below are imported: see the gc.freeze() after them

import dataclasses  # noqa: E402
import os  # noqa: E402
import signal  # noqa: E402
import sys  # noqa: E402
from typing import Annotated, Literal, Optional, Sequence  # noqa: E402

import tyro  # noqa: E402


import sac_jax  # noqa: E402
from sac_jax.config import SACConfig  # noqa: E402
from sac_jax.presets import DEFAULT_PRESET, PRESETS  # noqa: E402
from sac_jax import memory, parallel, run_checkpoint, run_dir, tracking  # noqa: E402
from sac_jax.run import FINISHED, INTERRUPTED, DeviceBusy, non_finite_state  # noqa: E402
from sac_jax.cli import (EXIT_CODES, PresetName, RunFailed, StopRequest,  # noqa: E402
                         after_failure, check_resume_flags, device_split, fail, kept,
                         parse_with_preset, positive, prng_seed, run_main, train_in_dir)

if __name__ == "__main__":
    # The imports above make about 160,000 objects that live on. With the collector off while
    # they were made, and those objects frozen now (no collection looks at them again), a warm
    # run's process spent 0.17-0.22 s in collections instead of 0.43-0.53 s, and its delivered
    # policy came 0.3-0.5 s sooner from process start (3 alternated runs, 2 CPU cores).
    gc.freeze()
    gc.enable()


@dataclasses.dataclass(frozen=True)
class TrainArgs:
    """Train SAC: one compiled program for the whole run, all seeds vmapped in it."""

    preset: PresetName = DEFAULT_PRESET
    """Base configuration; each SACConfig flag below overrides one of its fields (the defaults
    shown are this preset's)."""
    seeds: int = 1
    """Seeds trained at once in one vmapped program, split into equal groups over the local
    devices (on a CPU, one device per core: `sac_jax.parallel.cpu_device_per_core`)."""
    seed: int = 0
    """PRNG seed of the run; each seed's key is split from it."""
    out: Optional[str] = None
    """Run directory to create (must not exist); default runs/<preset>-<env>-<time>."""
    resume: Optional[str] = None
    """Continue the run saved in this directory from its checkpoint, with its own configuration
    (no other run or config flags)."""
    resume_step: Optional[int] = None
    """With --resume: the checkpoint to continue from, by environment step (default the newest;
    the run directory keeps the newest two)."""
    cache: bool = True
    """JAX's persistent compilation cache: a second run of the same configuration starts
    without compiling."""
    cache_dir: Optional[str] = None
    """Compilation cache directory (default $JAX_COMPILATION_CACHE_DIR or ~/.cache/sac-jax/jax)."""
    memory_check: bool = True
    """Refuse, before anything is written or compiled, a run whose peak memory (replay, state
    and a checkpoint's copy: `sac_jax.memory`) exceeds the memory available."""
    track: bool = False
    """Also log the run to Weights & Biases (needs `pip install -e ".[track]"`): the
    TensorBoard scalars at each evaluation point (step = environment steps), the config, the
    summary; `--resume` continues the same W&B run."""
    wandb_project: str = "sac-jax"
    """W&B project (with --track)."""
    wandb_entity: Optional[str] = None
    """W&B entity, a user or team (with --track; default: W&B's default entity)."""
    wandb_name: Optional[str] = None
    """W&B run name (with --track; default: the run directory's name)."""
    wandb_mode: Optional[Literal["online", "offline"]] = None
    """W&B mode (with --track; default $WANDB_MODE, else online); an offline run is uploaded
    later with `wandb sync`."""
    config: Annotated[SACConfig, tyro.conf.OmitArgPrefixes] = PRESETS[DEFAULT_PRESET]

    def __post_init__(self):
        positive("seeds", self.seeds)
        prng_seed("seed", self.seed)
        if self.resume_step is not None and self.resume is None:
            raise ValueError(f"--resume-step={self.resume_step}: only with --resume")


def parse_args(argv: Optional[Sequence[str]] = None) -> TrainArgs:
    """The command line as `TrainArgs` (`parse_with_preset`); a resumed run takes no run or
    config flags."""
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parse_with_preset(TrainArgs, argv, __doc__)
    if args.resume is not None:
        check_resume_flags(argv, args.resume, "run")
    return args


NON_FINITE_ADVICE = ("resuming would repeat the same updates: train anew with other settings, "
                     "e.g. lower learning rates")
"""What a run that stopped on a non-finite state can do next: a resumed run keeps its
configuration and is deterministic."""


def _new_run(args: TrainArgs):
    """(config, run info, run directory, memory line) of a fresh run; the directory is created
    last, once every input is known to be good and the run to fit in memory. ValueError on bad
    input (`memory.MemoryRefused` for a run that cannot fit)."""
    parallel.cpu_device_per_core(args.seeds)  # before JAX starts: a CPU's seeds over its cores
    info = run_dir.RunInfo(args.preset, args.seeds, args.seed)
    out = args.out or os.path.join(
        "runs", f"{args.preset}-{args.config.env}-{time.strftime('%Y%m%d-%H%M%S')}")
    run_dir.check_new(out)  # before the memory check's work
    fits = _memory_line(args, args.config, args.seeds)
    if args.track:
        tracking.check_available()
    run_dir.create(out, args.config, info.preset, info.seeds, info.seed)
    if args.track:
        tracking.save_settings(out, tracking.settings(
            args.wandb_project, args.wandb_entity, args.wandb_name, args.wandb_mode))
    return args.config, info, out, fits


def _memory_line(args: TrainArgs, config: SACConfig, seeds: int) -> str:
    """`memory.check`'s line (MemoryRefused if the run cannot fit), or what was skipped."""
    if not args.memory_check:
        return "memory not checked (--no-memory-check)"
    return memory.check(config, seeds)


def _resumed_run(args: TrainArgs):
    """(config, run info, run directory, (state, position), memory line) of the run in
    `--resume`."""
    config, info = run_dir.read_config(args.resume)
    parallel.cpu_device_per_core(info.runs)  # before JAX starts: a CPU's seeds over its cores
    if tracking.load_settings(args.resume) is not None:
        tracking.check_available()
    fits = _memory_line(args, config, info.runs)
    config, info, state, position = run_checkpoint.load_checkpoint(args.resume, args.resume_step)
    if run_dir.results_written(args.resume):  # else a finished state gets its result files
        raise ValueError(f"--resume={args.resume}: this run already finished")
    bad = non_finite_state(config, state, info.runs)
    if bad is not None:  # its next chunk would stop on it again
        raise ValueError(f"--resume={args.resume}: the state at step {position.env_steps} holds "
                         f"a non-finite {bad}; {NON_FINITE_ADVICE}")
    return config, info, args.resume, (state, position), fits


def _outcome(summary: dict) -> str:
    """What the run delivers: the delivered actors' confirmed returns, and when they were
    solved (per seed for up to 8 seeds, else a count and the time the last one was)."""
    returns, solved = summary["delivered_return"], summary["solved_at_step"]
    threshold = summary["solved_threshold"]
    if len(returns) <= 8:
        text = f"delivered policy return per seed {[round(r, 1) for r in returns]}"
        if threshold is None:
            return text
        if all(step is None for step in solved):
            return text + f"; not solved (>= {threshold:g})"
        if None in solved:  # '-': not solved
            steps = ", ".join("-" if step is None else str(step) for step in solved)
            return text + f"; solved (>= {threshold:g}) at step [{steps}]"
        return (text + f"; solved at step {solved}, after {summary['solved_wall_s']} s of "
                f"training ({summary['solved_process_s']} s from process start)")
    text = (f"delivered policy return mean {sum(returns) / len(returns):.1f} (min "
            f"{min(returns):.1f}, max {max(returns):.1f})")
    if threshold is None:
        return text
    text += f"; {sum(x is not None for x in solved)}/{len(returns)} seeds solved (>= {threshold:g})"
    if summary["all_solved_wall_s"] is not None:
        text += (f", the last after {summary['all_solved_wall_s']} s of training "
                 f"({summary['all_solved_process_s']} s from process start)")
    return text


def main(argv=None) -> int:
    # first, before JAX starts (here or from `sac-jax`): XLA's CPU kernels in sequence
    # (`compilation_cache.sequential_cpu_scheduler`); the devices once the seeds are known
    sac_jax.compilation_cache.sequential_cpu_scheduler()
    try:
        args = parse_args(argv)
        # before the memory check, whose state shapes the cache keeps (run_dir.state_template)
        sac_jax.compilation_cache.use_compilation_cache(args.cache, args.cache_dir)
        if args.resume:
            config, info, out, resume, fits = _resumed_run(args)
        else:
            (config, info, out, fits), resume = _new_run(args), None
    except ValueError as error:  # also UsageError, RunDirError and CheckpointError
        return fail(error, 2)
    seeds = info.seeds
    budget = (f"up to {config.run_steps} steps each (a seed stops once its delivered policy "
              f"scores {config.stop_at:g} over {config.stop_measurements} measurement"
              f"{'s' if config.stop_measurements > 1 else ''})"
              if config.stop_when_solved
              else f"{config.run_steps} steps each")
    print(f"{'resuming' if resume else 'preset'} {info.preset} on {config.env}: {seeds} "
          f"seed(s){device_split(seeds)}, {budget}, {config.num_envs} envs, "
          f"{config.updates_per_step} updates/iteration; {fits} -> {out}", flush=True)
    stop = StopRequest()
    previous = {s: signal.signal(s, stop) for s in EXIT_CODES}
    try:
        try:  # the memory was checked above, before the run directory was made
            result, code = train_in_dir(
                out, config, info.preset, seeds=seeds, seed=info.seed, settings=info.settings,
                resume=resume, stop=stop, runs=info.runs, started=STARTED,
                tracked=dict(dataclasses.asdict(config), **info.to_json()))
        finally:  # after the last save: a second signal during it stops at once
            for s, handler in previous.items():
                signal.signal(s, handler)
    except RunFailed as error:
        print(f"error: {error}; {after_failure(out, new=resume is None)}",
              file=sys.stderr, flush=True)
        return 1
    except (KeyboardInterrupt, DeviceBusy) as error:  # every file is whole or absent
        stop.leave_now(error, kept(out))
    s = result.summary
    if result.status == FINISHED:
        print(f"compile {s['compile_s']:.1f} s, run {s['run_s']:.1f} s; {_outcome(s)}; wrote "
              f"{out}", flush=True)
        return 0
    if result.status == INTERRUPTED:
        print(f"{result.message}; checkpoint saved: continue with --resume {out}",
              file=sys.stderr, flush=True)
        return code
    steps = run_checkpoint.saved_steps(out)  # non-finite: the run saved its state as it ended
    saved = (f"its delivered policy is saved with the state at step {steps[-1]}" if steps
             else "no checkpoint was written")
    print(f"error: {result.message}; {saved}; {NON_FINITE_ADVICE}", file=sys.stderr, flush=True)
    return 1


if __name__ == "__main__":
    run_main(main)
