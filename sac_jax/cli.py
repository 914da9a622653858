"""What the command-line scripts share: a tyro command line generated from a dataclass, whose bad
input ends with one line on stderr and no traceback (exit 2); a missing dependency ends the same
way with exit 1; and what scripts/train.py and scripts/sweep.py both do: presets as the
defaults of the config flags, the compile and progress lines, stopping on a signal, training
into a run directory and its result files, and the one line a run that fails ends with.

tyro reports bad input in multi-line panels; `parse` turns each report into one line naming the
flag and the value. It uses tyro's parse-error hook (`tyro._errors.on_parse_error`), which tyro
marks experimental: tyro is pinned to an exact version in pyproject.toml, and
tests/test_cli.py checks every kind of report.
"""

from __future__ import annotations

import contextlib
import math
import shutil
import signal
import sys
from typing import (TYPE_CHECKING, Any, Dict, Literal, NoReturn, Optional, Sequence, Tuple, Type,
                    TypeVar)

import tyro
from tyro import _errors

from envs._validate import is_positive_int
from sac_jax import (compilation_cache, malloc_arenas, metric_writers, parallel, run_checkpoint,
                     tracking)
from sac_jax.messages import first_line, os_reason
from sac_jax.presets import DEFAULT_PRESET, PRESETS
from sac_jax.records_process import RecordsProcess

if TYPE_CHECKING:
    from sac_jax.run import RunResult

T = TypeVar("T")
EXIT_CODES = {signal.SIGINT: 130, signal.SIGTERM: 143}
PresetName = Literal[tuple(PRESETS)]  # type: ignore[valid-type]


class MissingDependency(Exception):
    """A library or system package that the requested work needs is not available (exit 1)."""


class UsageError(ValueError):
    """Bad command-line input, as one line."""


def _one_line(event: _errors.ParseErrorEvent) -> None:
    """tyro's parse-error hook: raises UsageError with one line for `event`."""
    if isinstance(event, _errors.InstantiationFailure):
        message = " ".join(str(event.message).split())
        raise UsageError(message if event.argument is None
                         else f"{event.argument.display_name()}: {message}")
    if isinstance(event, _errors.InvalidChoice):
        raise UsageError(f"{event.argument.display_name()}={event.value!r}: must be one of "
                         f"{list(event.choices)}")
    if isinstance(event, _errors.BadValue):
        if event.offending_value is None:
            raise UsageError(f"{event.argument.display_name()}: expected a value")
        raise UsageError(f"{event.argument.display_name()}: takes no value, got "
                         f"{event.offending_value!r}")
    if isinstance(event, _errors.UnrecognizedArgs):
        raise UsageError(f"unrecognized arguments: {' '.join(event.tokens)} (see --help)")
    if isinstance(event, _errors.MissingArgs):
        names = [missing.arg.display_name() for missing in event.missing_arguments]
        raise UsageError(f"missing {', '.join(names)} (see --help)")
    raise UsageError(f"bad command line ({type(event).__name__}; see --help)")


def parse(cls: Type[T], argv: Optional[Sequence[str]] = None, *, default: Optional[T] = None,
          description: Optional[str] = None) -> T:
    """`tyro.cli(cls)` on `argv` (default: sys.argv[1:]), with `default` as the defaults when
    given; UsageError (one line) for bad input. `--help` prints and exits as usual."""
    argv = sys.argv[1:] if argv is None else list(argv)
    kwargs = {} if default is None else {"default": default}
    with _errors.on_parse_error(_one_line):
        return tyro.cli(cls, args=argv, description=description, **kwargs)


def positive(name: str, value: int) -> None:
    """ValueError naming the flag `--name` unless `value` is an integer >= 1."""
    if not is_positive_int(value):
        raise ValueError(f"--{name.replace('_', '-')}={value!r}: must be a positive integer")


def prng_seed(name: str, value: int) -> None:
    """ValueError naming the flag `--name` unless `value` is an integer in [0, 2**32): a PRNG
    key holds 32 bits of its seed, so 2**32 would give seed 0's keys."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < 2 ** 32:
        raise ValueError(f"--{name.replace('_', '-')}={value!r}: must be an integer in "
                         "[0, 2**32)")


class LeaveNow(Exception):
    """Raised by a script's `main` that has said why in one line and must exit with `code`
    without waiting for the device, which may still run the chunk it left (`run_main`)."""

    def __init__(self, code: int):
        super().__init__(code)
        self.code = code


def run_main(main) -> None:
    """`sys.exit(main())`; on `LeaveNow`, `os._exit(code)` after flushing: an interpreter
    shutting down waits for the device's running computation (a minute, measured). When the
    reader of standard output has gone (`... --help | head -3`), exit 1 without a traceback.
    Before `main`, the process's malloc arenas are capped (`sac_jax.malloc_arenas`)."""
    import os

    malloc_arenas.cap_arenas()

    try:
        code = main()
    except LeaveNow as leave:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(leave.code)
    except BrokenPipeError:
        # what is left in stdout's buffer goes nowhere, not into a second error at exit
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        code = 1
    sys.exit(code)


def device_split(seeds: int) -> str:
    """" over D <platform> devices" when `seeds` seeds are split over several devices
    (`sac_jax.parallel.seed_devices`), else ""."""
    devices = parallel.seed_devices(seeds)
    return (f" over {len(devices)} {devices[0].platform.upper()} devices" if len(devices) > 1
            else "")


def fail(error: Exception, code: int) -> int:
    """Prints `error` as one 'error: ...' line on stderr; returns the exit code `code`."""
    print(f"error: {error}", file=sys.stderr)
    return code


RESUME_FLAGS = ("--resume", "--resume-step", "--cache", "--no-cache", "--cache-dir",
                "--memory-check", "--no-memory-check")
"""The flags a resumed run or sweep accepts; it keeps its own configuration."""


def check_resume_flags(argv: Sequence[str], resume: str, what: str) -> None:
    """ValueError naming the first flag of `argv` other than `RESUME_FLAGS`: a resumed `what`
    ("run", "sweep") keeps its own configuration."""
    given = [t.partition("=")[0] for t in argv if t.startswith("--")]
    other = [flag for flag in given if flag not in RESUME_FLAGS]
    if other:
        raise ValueError(f"--resume={resume}: a resumed {what} keeps its own configuration; "
                         f"remove {other[0]}")


def parse_with_preset(cls, argv: Sequence[str], description: str):
    """The command line as `cls` (a dataclass with `preset` and `config` fields), the SACConfig
    defaults taken from `--preset` (an unknown preset is reported by the parse). UsageError
    (one line) for bad input."""
    preset = DEFAULT_PRESET
    for i, token in enumerate(argv):
        name, _, value = token.partition("=")
        if name == "--preset":
            value = value or (argv[i + 1] if i + 1 < len(argv) else "")
            preset = value if value in PRESETS else DEFAULT_PRESET
    return parse(cls, argv, default=cls(preset=preset, config=PRESETS[preset]),
                 description=description)


def duration(seconds: float) -> str:
    """`seconds` as a person reads a wait: "42 s", "12 min", "3.1 h"."""
    if seconds < 100:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.0f} min" if seconds < 6000 else f"{seconds / 3600:.1f} h"


def progress_line(step: int, point: dict, seeds: int, elapsed: float,
                  total_steps: Optional[int] = None) -> str:
    """One line per evaluation point (means over seeds): the last actor's evaluation, the
    delivered (kept) actor's score, training return, temperature, losses, speed; a
    value not defined at this point (e.g. no training episode ended since the last evaluation,
    no update after every seed stopped) shows as "-". Given the run's `total_steps` per seed,
    before the last point it tells the time left to the end of them at the speed so far,
    elapsed * (total_steps - step) / step (a run whose seeds stop once solved may end sooner;
    none once all have stopped, where the run ends).
    With a solved threshold it ends with how many seeds' delivered actors are solved, and how
    many seeds have stopped learning."""
    def number(name, spec):
        value = point.get(name, math.nan)
        return format(value, spec) if math.isfinite(value) else "-".rjust(len(format(0.0, spec)))

    left = ""
    if total_steps is not None and 0 < step < total_steps and point.get("stopped", 0) < 1:
        left = f", {duration(elapsed * (total_steps - step) / step)} left"
    solved = ""
    if "solved" in point:
        solved = f" | solved {round(point['solved'] * seeds)}/{seeds}"
        if point.get("stopped"):
            solved += f", stopped {round(point['stopped'] * seeds)}"
    return (f"step {step:>8d} | eval {number('eval_return', '9.1f')} | delivered "
            f"{number('delivered_return', '9.1f')} | train {number('train_return', '9.1f')} | "
            f"alpha {number('alpha', '.3f')} | critic {number('critic_loss', '.3g')} | actor "
            f"{number('actor_loss', '.3g')} | {step * seeds / max(elapsed, 1e-9):8.0f} steps/s "
            f"| {elapsed:6.1f} s{left}{solved}")


class CompileNotice:
    """The console's line while a run's programs are built, the longest wait of a first run
    (`fast`: about 10 s on 2 CPU cores; later runs read the programs from the cache): made,
    it prints "compiling the programs (where they are cached) ..." and leaves the line open;
    `ready(seconds)` (`run_training`'s `on_ready`) ends it with the seconds (or, where the line
    was ended before, says them on a line of its own); `close()` ends it if `ready` has not
    come, so that an error's or a signal's line starts on a line of its own."""

    def __init__(self):
        directory = compilation_cache.active_directory()
        where = (f"cached in {directory} for later runs" if directory
                 else "no cache: every run compiles them")
        print(f"compiling the programs ({where}) ...", end="", flush=True)
        self.open = True

    def ready(self, seconds: float) -> None:
        print(f" {seconds:.1f} s" if self.open else f"programs ready after {seconds:.1f} s",
              flush=True)
        self.open = False

    def close(self) -> None:
        if self.open:
            print(flush=True)
            self.open = False


class StopRequest:
    """Signal handler: the first SIGINT/SIGTERM asks the run to stop at the next chunk boundary
    (after saving); a second one stops at once. `notice`: the run's `CompileNotice`, whose open
    line a signal's message ends first."""

    def __init__(self):
        self.signal = None
        self.notice: Optional[CompileNotice] = None

    def __call__(self, signum, frame):
        if self.signal is not None:
            raise KeyboardInterrupt
        self.signal = signum
        if self.notice is not None:
            self.notice.close()
        print(f"{signal.Signals(signum).name}: stopping after the current chunk; saving a "
              "checkpoint (again to stop at once)", file=sys.stderr, flush=True)

    def leave_now(self, error: BaseException, then: str) -> NoReturn:
        """After a second signal (`error` a KeyboardInterrupt) or a stop whose chunk did not
        end in time (`sac_jax.run.DeviceBusy`): one 'error:' line ending in `then`, then
        `LeaveNow` at once, because the device may still run the chunk, which an exiting
        interpreter would wait for."""
        name = signal.Signals(self.signal or signal.SIGINT).name
        why = (f"{name} again: stopped at once" if isinstance(error, KeyboardInterrupt)
               else f"{name}: {error}; stopped without it")
        print(f"error: {why}; {then}", file=sys.stderr, flush=True)
        raise LeaveNow(EXIT_CODES.get(self.signal, 130))


def write_results(out: str, config, preset: str, result: RunResult, write_curves) -> None:
    """metrics.csv, summary.json and, if the run has points, curves.png, drawn by
    `write_curves` (`plots.write_curves`'s arguments; a `RecordsProcess`'s)."""
    metric_writers.write_metrics(out, result.metrics, result.points)
    metric_writers.write_summary(out, dict(result.summary, preset=preset))
    if result.points:
        write_curves(out, result.metrics, result.points, f"{config.env}, preset {preset}",
                     result.summary["solved_threshold"])


class RunFailed(Exception):
    """What a run cannot go on from, as one line: a checkpoint, TensorBoard's records or the
    result files that cannot be written (e.g. a full disk), W&B failing (no login, no
    network), or device memory exhausted."""


def train_in_dir(out: str, config, preset: str, *, seeds: int, seed: int, settings, resume,
                 stop: StopRequest, runs: int, tracked: Dict[str, Any], started: float,
                 stop_on_non_finite: bool = True) -> Tuple["RunResult", int]:
    """Trains `config` in the run directory `out` (`run_dir.create`'s, or the one whose
    checkpoint `resume` = (state, position) holds), as scripts/train.py and each program of
    scripts/sweep.py do: the compile line, a progress line per evaluation point (`runs` runs),
    TensorBoard records, W&B's where the directory's tracking settings ask (`tracked`: the
    run's W&B config), checkpoints written in the background, the result files; `started` is
    `time.perf_counter()` at the process's start (`run_training`'s). Returns the
    `RunResult` and its exit code: 0 finished, the signal's if `stop` stopped it, else 1.
    Raises `RunFailed` (exit 1), and KeyboardInterrupt or `sac_jax.run.DeviceBusy` as
    `run_training` does; every file is whole or absent. W&B failing as it ends its record,
    after the result files, is a one-line warning that leaves the exit code as it was."""
    import jax

    from sac_jax.run import FINISHED, INTERRUPTED, evaluation_points, run_training

    history = evaluation_points(config, resume[0]) if resume else []  # the points done
    records = RecordsProcess(out, history)  # TensorBoard's and curves.png, by a child process
    wandb_run = tracking.follow(out, tracked, history)

    def on_point(step, means, eval_returns, elapsed):
        print(progress_line(step, means, runs, elapsed, config.run_steps), flush=True)
        with _written("TensorBoard's records"):  # raises what the child failed to write
            records.add_point(step, means, eval_returns)
        if wandb_run is not None:
            try:  # raises what failed on its thread since the last point
                wandb_run.add_point(step, means, eval_returns)
            except Exception as error:
                raise RunFailed(f"W&B: {first_line(error)}") from None

    checkpoints = run_checkpoint.CheckpointWriter(out)
    notice = stop.notice = CompileNotice()

    switch_interval = sys.getswitchinterval()

    def ready(seconds):
        notice.ready(seconds)
        sys.setswitchinterval(TRAINING_SWITCH_INTERVAL_S)
        records.start()
    with contextlib.closing(records):
        try:
            try:
                result = run_training(
                    config, seeds=seeds, seed=seed, settings=settings, resume=resume,
                    on_ready=ready, on_point=on_point, on_checkpoint=checkpoints.save,
                    should_stop=lambda: stop.signal is not None, started=started,
                    check_memory=False, stop_on_non_finite=stop_on_non_finite)  # checked before
            finally:
                sys.setswitchinterval(switch_interval)
                notice.close()
                try:
                    with _written("TensorBoard's records"):
                        records.close_tensorboard()
                finally:  # waits for the checkpoint under way, even if a signal came first
                    checkpoints.close()
        except run_checkpoint.CheckpointWriteError as error:
            raise RunFailed(str(error)) from None
        except jax.errors.JaxRuntimeError as error:
            if "RESOURCE_EXHAUSTED" not in str(error):
                raise
            raise RunFailed(f"out of memory on {jax.local_devices()[0].platform} "
                            f"({_xla_reason(error)}): lower --buffer-size or --seeds") from None
        with _written("the result files"):  # the state is saved: a resume writes them again
            write_results(out, config, preset, result, records.write_curves)
    code = {FINISHED: 0, INTERRUPTED: EXIT_CODES.get(stop.signal, 130)}.get(result.status, 1)
    if wandb_run is not None:
        try:  # the run and its files are whole: W&B failing now costs only its own record
            wandb_run.finish(dict(result.summary, preset=preset), code)
        except Exception as error:
            print(f"warning: W&B: {first_line(error)}; the run's results are in {out}",
                  file=sys.stderr, flush=True)
    return result, code


TRAINING_SWITCH_INTERVAL_S = 2e-4
"""The interpreter's thread switch interval while a run trains (CPython's default: 5 ms). On a
GPU the host loop takes the GIL twice per chunk to call its programs, and each call waited up to
that long for a thread importing beside training (orbax's, TensorBoard's writer's and
matplotlib's). rejax's Pendulum-v1 SAC, 1 seed, 20 chunks, on an H100 (2026-12-05, 3
alternated warm runs each, `scripts/train.py` with benchmarks/rejax_peer.py's flags): run time
1.89-1.93 s against 1.97-1.99 s at the default; the jitted program 1.73 s. `run_training` also
holds such imports back while its loop works between chunks
(`sac_jax.background.LoopImportGate`), and TensorBoard's writer and matplotlib are now imported
in another process (`sac_jax.records_process`). On 2 CPU cores, as fast as at the default
(5.93 s against 5.94 s, medians of 5 rounds). Compiling, before it is set, runs at the
default."""


@contextlib.contextmanager
def _written(what: str):
    """`RunFailed` naming `what` and the system's reason for an OSError the block raises (a
    full disk, a directory made read-only)."""
    try:
        yield
    except OSError as error:
        where = f" ({error.filename})" if error.filename else ""
        raise RunFailed(f"{what} could not be written{where}: {os_reason(error)}") from None


def _xla_reason(error: Exception) -> str:
    """The first line of an XLA error, without its status code: "Out of memory while trying
    to allocate 5.26GiB with allocator GPU_0_bfc on device 0"."""
    return first_line(error).split(": ", 1)[-1].split(" [", 1)[0]


def kept(out: str, resume: Optional[str] = None) -> str:
    """Which checkpoint of the run directory `out` that ended early is left to continue from
    with --resume `resume` (default `out`)."""
    steps = run_checkpoint.saved_steps(out)
    if not steps:
        return "no checkpoint was written"
    return (f"the last checkpoint written (step {steps[-1]}) is kept: continue with --resume "
            f"{resume or out}")


def after_failure(out: str, new: bool, resume: Optional[str] = None) -> str:
    """`kept`, after a `RunFailed` of a `new` run whose directory holds no checkpoint has
    removed it (nothing in it is worth keeping, and its name is free again)."""
    if new and not run_checkpoint.saved_steps(out):
        shutil.rmtree(out, ignore_errors=True)
        return f"{out} removed"
    return kept(out, resume)
