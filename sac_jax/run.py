"""Running a configuration from the host: compile once, train all seeds in one program, follow
progress, check that the state stays finite, stop cleanly on request, and resume.

The compiled units are `jax.vmap(advance)` and `jax.vmap(evaluate)` (axes `SEED_AXES`; for one
seed, the part itself with the seed axis taken off and put back,
`sac_jax.parallel.over_seed_axis`) from `sac_jax.train.make_train_parts`: the iterations up to
the next boundary (the prefill's end or the next evaluation point), then that point's
evaluation (`Chunk`). The host calls them once per boundary (donating the state, so the replay
buffers are updated in place), and between calls reads the points, checks for non-finite
parameters and asks `should_stop`. The programs hold no host callback, so JAX's persistent
compilation cache keeps them. Because each chunk is a pure function of the state, a run
stopped at a chunk boundary and resumed from that state ends exactly where the uninterrupted run
does.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import dataclasses
import functools
import gc
import threading
import time
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import jax
import numpy as np

import envs
from sac_jax import background, hyperparams, memory
from sac_jax.config import SACConfig
from sac_jax.compilation_cache import compiler_options, program_directory
from sac_jax.parallel import seed_axis, seed_devices, seed_mapping
from sac_jax.position import Position
from sac_jax.program_cache import cached_lower, without_locations
from sac_jax.run_dir import state_template
from sac_jax.train import SEED_AXES, RunnerState, make_train_parts, non_finite_fields

FINISHED, INTERRUPTED, NON_FINITE = "finished", "interrupted", "non-finite"


class DeviceBusy(Exception):
    """A stop was asked for while the device still ran a chunk, and the chunk did not end
    within the grace period: the run was left without waiting for it (its last checkpoint is
    the last saved one). The process should exit: the device may still be running."""


STOP_CHECK_S = 0.05
"""How often a wait for the device (`_wait`) looks whether a stop has been asked for."""


def _wait(array: jax.Array, should_stop: Optional[Callable[[], bool]], grace_s: float,
          gate: Optional[background.LoopImportGate] = None) -> None:
    """Waits for `array`, blocked on a helper thread while this one sleeps on an event: signal
    handlers run during the wait (a blocking wait on this thread holds them off until it
    returns), and the wait takes no processor time from the device's threads. Polling
    `is_ready()` every 0.2 ms instead, rejax's Pendulum-v1 configuration trained in 6.21 s
    against 5.99 s (`run_training`, medians of 8 alternated runs, 2 CPU cores of a Zen 4 AMD
    EPYC; blocking on this thread, 5.95 s). Raises `DeviceBusy` once `should_stop()` has
    been true for `grace_s` seconds of the wait (looked at first and every `STOP_CHECK_S`).
    Other threads' imports held back by `gate` run while this one sleeps."""
    if array.is_ready():
        return
    done = threading.Event()

    def block():
        with contextlib.suppress(Exception):  # a failed program's error: the caller's fetch
            array.block_until_ready()         # raises it
        done.set()

    threading.Thread(target=block, name="device wait", daemon=True).start()
    asked = None
    with gate.waiting() if gate is not None else contextlib.nullcontext():
        while True:
            if should_stop is not None and should_stop():
                asked = time.perf_counter() if asked is None else asked
                if time.perf_counter() - asked >= grace_s:
                    raise DeviceBusy(f"the device was still running a chunk {grace_s:g} s "
                                     "after the stop was asked for")
            if done.wait(STOP_CHECK_S):
                return


@dataclasses.dataclass
class RunResult:
    """`metrics`: numpy arrays (seeds, num_evals), NaN after the `points` evaluations done, with
    `wall_s` (training seconds, compile excluded, at each point) and `steps_per_s` (environment
    steps per second of one seed) added to the program's metrics;
    `status`: FINISHED, INTERRUPTED (`should_stop` said so) or NON_FINITE (`message` says which
    quantity, seed, and the chunk's environment steps); `position`: where the host loop ended."""

    state: RunnerState
    metrics: Dict[str, np.ndarray]
    points: int
    status: str
    message: str
    position: Position
    summary: dict


def _nanmean(values) -> float:
    """Mean of the finite values, NaN if there are none (without numpy's warning)."""
    finite = [v for v in values if np.isfinite(v)]
    return float(np.mean(finite)) if finite else float("nan")


def point_means(config: SACConfig, point: Dict[str, np.ndarray]) -> Dict[str, float]:
    """What `run_training` reports of one evaluation point (`point`: {metric: value per seed},
    one column of the state's `outputs`): each metric's mean over the seeds that have it;
    `solved`, for a task with a solved threshold, the fraction of seeds whose delivered
    actor has reached it; `stopped` the fraction of seeds stopped (the program's `stopped`
    output). The figures of a point are a function of the point's outputs alone, and can be
    recomputed from a checkpoint (`evaluation_points`)."""
    means = {k: _nanmean(v) for k, v in point.items()}
    threshold = envs.spec(config.env).solved_return
    if threshold is not None:
        means["solved"] = float(np.mean(np.asarray(point["delivered_return"]) >= threshold))
    return means


def points_done(config: SACConfig, iteration: int) -> int:
    """Evaluation points a state at `iteration` iterations has done."""
    return max(0, (int(iteration) - config.prefill_iterations) // config.iterations_per_eval)


def evaluation_points(config: SACConfig, runner: RunnerState
                      ) -> List[Tuple[int, Dict[str, float], np.ndarray]]:
    """[(env_steps, `point_means`, each seed's evaluation return)] of every evaluation point
    the state `runner` (e.g. a checkpoint's) has done, in order: what `on_point` was called
    with, for a writer rebuilding its record of a resumed run."""
    outputs = jax.device_get(runner.outputs)
    return [_point(config, outputs, p)
            for p in range(points_done(config, jax.device_get(runner.iteration)))]


def _point(config: SACConfig, outputs: Dict[str, np.ndarray], p: int
           ) -> Tuple[int, Dict[str, float], np.ndarray]:
    """(environment step, `point_means`, each seed's evaluation return) of evaluation point `p`
    of a state's `outputs` (on the host: {metric: (seeds, num_evals)})."""
    point = {k: np.asarray(v)[:, p] for k, v in outputs.items()}
    return int(point["env_steps"][0]), point_means(config, point), point["eval_return"]


def solved_at(returns: np.ndarray, env_steps: np.ndarray, threshold: float) -> Optional[int]:
    """First environment step from which the returns (e.g. the delivered actor's kept score,
    which re-measurements can lower) stay at or above `threshold` to the last one, or None."""
    below = np.nonzero(~(np.asarray(returns) >= threshold))[0]
    first = below[-1] + 1 if below.size else 0
    return int(env_steps[first]) if first < len(returns) else None


def _finite_flags(tree):
    """Per leaf, per seed: whether every entry is finite, computed on the host (a run reads them
    only once `RunnerState.non_finite` says a seed's state is no longer finite).
    Leaves (seeds, ...) -> (seeds,)."""
    return jax.tree_util.tree_map(
        lambda x: np.all(np.isfinite(x), axis=tuple(range(1, np.ndim(x)))), jax.device_get(tree))


def first_non_finite(flags, first: Optional[Sequence[Optional[str]]] = None) -> Optional[str]:
    """'<array> of seed <s>' for the first seed whose vmapped `SACState` holds a NaN or an
    infinity, from its `_finite_flags`; None if all are finite. The array is the first
    non-finite one of the field `first[s]` (the field that went non-finite first, from
    `RunnerState.non_finite`) if given, else the first in the state's order."""
    flat = jax.tree_util.tree_flatten_with_path(jax.device_get(flags))[0]
    bad = [(jax.tree_util.keystr(path, simple=True, separator="/"), np.asarray(ok))
           for path, ok in flat if not np.all(ok)]  # named only when bad: this runs per chunk
    if not bad:
        return None
    seed = min(int(np.argmin(ok)) if ok.ndim else 0 for _, ok in bad)
    names = [name for name, ok in bad if ok.ndim == 0 or not ok[seed]]
    field = first[seed] if first is not None and seed < len(first) else None
    named = [name for name in names if field is not None and name.split("/")[0] == field]
    return f"{(named or names)[0]} of seed {seed}"


def non_finite_name(sac, codes: np.ndarray, fields: Sequence[str]) -> str:
    """What a run names when a seed's `RunnerState.non_finite` code (one per seed in `codes`,
    1 + an index in `fields`) is set: the array `first_non_finite` finds in `sac`, or, where no
    array of `sac` holds a NaN or an infinity any more, the field the code gives."""
    first = [fields[c - 1] if c else None for c in codes]
    lowest = int(np.argmax(np.asarray(codes) != 0))
    return first_non_finite(_finite_flags(sac), first) or f"{first[lowest]} of seed {lowest}"


def compiled_program(config: SACConfig, seeds: int, swept: Tuple[str, ...] = (),
                     seed_keys: Optional[int] = None):
    """`_compiled_program` (kept per (config, seeds, swept, seed_keys), however they are
    passed; `seed_keys` defaults to `seeds`)."""
    return _compiled_program(config, seeds, tuple(swept), seed_keys or seeds)


def runs_init(init: Callable, seed_keys: int) -> Callable:
    """`init(key, *hyperparams)` as `init(run, seed, *hyperparams)`: run `run` (of a program's
    runs, numbered as `sac_jax.hyperparams.run_index` numbers them) starts from key
    `run % seed_keys` of `jax.random.split(jax.random.key(seed), seed_keys)`, so that every
    setting of a sweep trains the same keys. The split is in the init program, not on the
    host: each computation run outside a compiled program is compiled when first run, and
    those of the keys cost a warm start about 0.04-0.06 s (2 CPU cores)."""
    return lambda run, seed, *rest: init(
        jax.random.split(jax.random.key(seed), seed_keys)[run % seed_keys], *rest)


def start_args(seed: int, runs: int) -> Tuple[np.ndarray, np.ndarray]:
    """The (run, seed) arguments of the compiled init program of `runs` runs (`runs_init`):
    the runs' numbers, and `seed` as `jax.random.key(seed)` takes a Python int (in 64 bits,
    then JAX's default integer type)."""
    return (np.arange(runs, dtype=np.int32),
            np.asarray(np.int64(seed)).astype(jax.dtypes.canonicalize_dtype(np.int64)))


@contextlib.contextmanager
def _collector_paused():
    """Python's cyclic garbage collector off inside the block (as it was, after). Tracing
    allocates objects by the million, and the collector's passes over them cost a cold `fast`
    run 0.7 s (1.32 s in collections against 0.62 s with the pause, `gc.callbacks`, 2 CPU
    cores), nearly all on the tracing thread that every compilation waits for."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


@functools.lru_cache(maxsize=4)
def _compiled_program(config: SACConfig, seeds: int, swept: Tuple[str, ...], seed_keys: int):
    """(parts, compiled vmapped init, `Chunk` of the compiled vmapped `advance` and `evaluate`,
    the state's sharding) for `seeds` seeds of `config` (with the hyperparameters `swept`
    traced, one value per seed: `init(*start_args(seed, seeds), {name: (seeds,)})`, from
    `seed_keys` keys, `runs_init`), the seeds split into equal groups over the local devices
    (`sac_jax.parallel.seed_devices`). Kept per (config, seeds, swept, seed_keys), so later
    runs of the same shapes in this process neither trace nor compile again; other processes
    find the traced programs and their executables in `sac_jax.program_cache` (else the
    executables in the persistent compilation cache)."""
    directory = program_directory()
    options = compiler_options(config.make_env())

    def compiling(name, fn, in_axes, out_axes, args, result, donate):
        """(`jax.jit`'s placement, a call that compiles `fn` mapped over the seeds for `args`):
        through the program cache where it is on, else lowered now."""
        mapped, placement = seed_mapping(fn, seeds, in_axes, out_axes)
        if directory is None:
            return placement, functools.partial(without_locations(jax.jit(
                mapped, donate_argnums=(0,) if donate else (), **placement).lower(
                *args)).compile, compiler_options=options)
        name = f"{name} of {seed_keys} keys" if name == "init" else name
        return placement, cached_lower(mapped, f"{name} {config!r}", args, result, directory,
                                       donate_first=donate, compiler_options=options,
                                       **placement).compile

    # XLA compiles without Python's lock: each program compiles while the next is traced
    with concurrent.futures.ThreadPoolExecutor(4) as pool:
        with _collector_paused():
            parts = make_train_parts(config, seed_axis=seed_axis(seeds))
            keys = jax.eval_shape(lambda: jax.random.split(jax.random.key(0), seeds))
            values = {name: jax.ShapeDtypeStruct((seeds,), jax.dtypes.canonicalize_dtype(float))
                      for name in swept}
            swept_values = [values] if swept else []
            # the state's shapes: traced once for the memory check, unless hyperparameters
            # are traced too (then the state holds them)
            state = (jax.eval_shape(jax.vmap(parts.init, out_axes=SEED_AXES), keys,
                                    *swept_values)
                     if swept else state_template(config, seeds))
            runs, seed = (jax.ShapeDtypeStruct(x.shape, x.dtype) for x in start_args(0, seeds))
            compiled = []
            for name, part, in_axes, out_axes, args, result, donate in (
                    ("init", runs_init(parts.init, seed_keys),
                     (0, None, *(0,) * len(swept_values)), SEED_AXES, [runs, seed, *swept_values],
                     state, False),
                    ("advance", parts.advance, (SEED_AXES,), SEED_AXES, [state], state, True),
                    ("evaluate", parts.evaluate, (EVALUATED_AXES,), EVALUATED_AXES,
                     [Chunk.evaluated(state)], Chunk.evaluated(state), True)):
                placement, compile = compiling(name, part, in_axes, out_axes, args, result,
                                               donate)
                compiled.append(pool.submit(compile))
                if name == "advance":  # where the state lives: split as its arguments are
                    sharding = (placement["in_shardings"][0] if placement
                                else jax.local_devices()[0])
        if gc.isenabled():
            gc.collect(1)  # tracing's garbage (younger generations), while XLA compiles
        init, advance, evaluate = (program.result() for program in compiled)
        return parts, init, Chunk(advance, evaluate), sharding


class Chunk:
    """The host's chunk: the compiled `advance` (`sac_jax.train.TrainParts`), then the
    compiled `evaluate` on the state less its environments and replay buffers, which
    evaluation neither reads nor writes (so its program neither holds nor copies them).
    Two programs rather than one `chunk`, because XLA compiles the first while the second is
    traced and both at once: `fast`'s programs were ready 2.4 s sooner on 2 CPU cores (8.2 s
    against 10.6 s from the start of tracing); the host dispatches both per chunk."""

    def __init__(self, advance, evaluate):
        self.advance, self.evaluate = advance, evaluate

    @staticmethod
    def evaluated(runner: RunnerState) -> RunnerState:
        """What the evaluation program takes and returns: `runner` less `env` and `buffer`."""
        return runner.replace(env=None, buffer=None)

    def __call__(self, runner: RunnerState) -> RunnerState:
        runner = self.advance(runner)
        return self.evaluate(self.evaluated(runner)).replace(env=runner.env,
                                                             buffer=runner.buffer)


EVALUATED_AXES = Chunk.evaluated(SEED_AXES)
"""`SEED_AXES` of what `Chunk.evaluated` keeps of a runner."""


compiled_program.cache_clear = _compiled_program.cache_clear
compiled_program.cache_info = _compiled_program.cache_info


def run_training(config: SACConfig, seeds: int = 1, seed: int = 0, *,
                 settings: Optional[Dict[str, Sequence[float]]] = None,
                 resume: Optional[tuple] = None,
                 on_ready: Optional[Callable[[float], None]] = None,
                 on_point: Optional[Callable[[int, dict, np.ndarray, float], None]] = None,
                 on_checkpoint: Optional[Callable[[RunnerState, dict], None]] = None,
                 should_stop: Optional[Callable[[], bool]] = None,
                 started: Optional[float] = None, check_memory: bool = True,
                 stop_on_non_finite: bool = True, stop_grace_s: float = 10.0) -> RunResult:
    """Trains `seeds` seeds (keys split from `seed`), vmapped in one program (split into equal
    groups over the local devices, `sac_jax.parallel.seed_devices`) driven one chunk at a time. With
    `config.stop_when_solved` the run ends as FINISHED once every seed has stopped. While the
    host loop works between chunks, other threads' imports of modules not loaded yet wait,
    for at most `sac_jax.background.MAX_IMPORT_HOLD_S` each time (`LoopImportGate`).

    settings: {name: [value per setting]} of hyperparameters (`sac_jax.hyperparams.NAMES`) to
        sweep: each setting (`sac_jax.hyperparams.sweep`) trains the same `seeds` keys, all
        S x seeds runs in the one program, setting-major (run r = setting r // seeds, key
        r % seeds); every per-seed figure of the result then has S x seeds entries.
    resume: `(state, Position)` read from a checkpoint; the run continues from there.
    on_ready(seconds): once, when the programs are built (traced and compiled, or read from the
        caches) and the starting state is dispatched, with the seconds that took (what this
        call adds to the summary's `compile_s`).
    on_point(env_steps, means, eval_returns, elapsed_s): at every evaluation point, with the
        metrics averaged over seeds and each seed's evaluation return; for a task with a solved
        threshold (`envs.spec(env).solved_return`), means["solved"] is the fraction of seeds whose
        delivered actor has reached it (`delivered_return`), and means["stopped"] the fraction
        stopped.
    on_checkpoint(state, position): after every evaluation point and when stopping on request,
        with the loop's `Position` (`ends_run`: whether the run ends there, at its last point
        or a stop);
        the state is not touched afterwards until the call returns (save it there).
    should_stop(): polled after every chunk; True ends the run as INTERRUPTED. Also polled while
        the host waits for a chunk: if it stays True for `stop_grace_s` seconds before the chunk
        ends, `DeviceBusy` is raised (the last saved checkpoint stays the last good one).
    started: `time.perf_counter()` at the start of the process, for the summary's times from
        process start (default: this call's start).
    check_memory: refuse (`sac_jax.memory.MemoryRefused`, before anything is compiled) a run
        whose peak memory exceeds what is available (`sac_jax.memory.check`).
    A parameter, optimiser state or temperature that becomes non-finite ends the run as
    NON_FINITE without calling `on_checkpoint` again, so the last saved checkpoint stays good;
    unless not `stop_on_non_finite` (a sweep, where one setting may diverge): then the others
    train on, and the summary's `non_finite_at_step` gives, per seed, the end of the chunk (the
    environment step of the evaluation point, or of the prefill's end) in which its state
    became non-finite (its delivered actor stays the last one confirmed before).
    """
    configs, values = hyperparams.sweep(config, settings, seeds)
    config, seed_keys, seeds = configs[0], seeds, seeds * len(configs)
    if check_memory:
        memory.check(config, seeds)
    t0 = time.perf_counter()
    parts, init, chunk, sharding = compiled_program(config, seeds, tuple(values), seed_keys)
    # before the state exists (the programs' temporaries are read after the run: XLA's
    # analysis of a loaded executable took 0.03 s each, 2 CPU cores)
    process, available = memory.process_bytes(), memory.available()[0]
    if resume is None:
        runner = init(*start_args(seed, seeds), *([values] if values else []))
        position = Position(startup_s=t0 - (t0 if started is None else started))
    else:
        runner, position = jax.device_put(resume[0], sharding), resume[1].copy()
    built = time.perf_counter() - t0
    position.compile_s += built
    if on_ready is not None:
        on_ready(built)
    start = time.perf_counter() - position.run_s
    status, message = FINISHED, ""

    def points_reached(state) -> int:
        _wait(state.iteration, should_stop, stop_grace_s, gate)
        # raises the program's error, e.g. RESOURCE_EXHAUSTED for an allocation that failed
        # (fetching an output that did not fail, such as the iteration, then waits forever)
        jax.block_until_ready(state)
        return points_done(config, state.iteration)

    def all_stopped(state) -> bool:
        return config.stop_when_solved and bool(np.all(jax.device_get(state.stopped)))

    # other threads' imports (the scripts': TensorBoard's writer, orbax) wait
    # while this loop works between chunks, and run while it waits for the device
    with background.LoopImportGate() as gate:
        points = points_reached(runner)
        finished = lambda state: int(state.iteration) >= parts.num_iterations
        while not finished(runner) and not all_stopped(runner):
            start_steps = int(runner.iteration) * config.num_envs
            runner = chunk(runner)
            position.chunks_done += 1
            new_points = points_reached(runner)
            host_start = time.perf_counter()  # the device waits from here to the next chunk
            position.run_s = host_start - start
            steps = int(runner.iteration) * config.num_envs
            # a state gone non-finite ends the run after this chunk's point is followed and saved:
            # its delivered actors were selected by finite evaluations, and are what it hands over
            message = _non_finite(config, runner, seeds, position, (start_steps, steps),
                                  stop_on_non_finite)
            reached = new_points > points
            if reached:
                points = new_points
                # indexed on the host: a device-side index would compile an op per new point
                step, means, returns = _point(config, jax.device_get(runner.outputs), points - 1)
                position.walls[step] = position.run_s
                if on_point is not None:
                    on_point(step, means, returns, position.run_s)
            stop = should_stop is not None and should_stop()
            position.env_steps = steps
            position.ends_run = bool(message or stop or finished(runner) or all_stopped(runner))
            if on_checkpoint is not None and (reached or stop or message):  # the last chunk ends
                on_checkpoint(runner, position)  # a period
            position.host_s += time.perf_counter() - host_start
            if message:
                status = NON_FINITE
                break
            if stop and not finished(runner):
                status, message = INTERRUPTED, f"stopped at environment step {steps}"
                break

    position.run_s = time.perf_counter() - start
    # a checkpoint's copy counted where it fits, as the writer makes it
    model = memory.need(config, seeds, available=available, process=process,
                        temporaries=memory.temporaries((chunk.advance, chunk.evaluate),
                                                       devices=len(seed_devices(seeds))))
    metrics = _run_metrics(config, runner, position, points)
    summary = dict(run_summary(config, metrics, points, position,
                               jax.device_get(runner.delivered.env_steps),
                               jax.device_get(runner.stopped), model),
                   seeds=seeds, seed_devices=len(seed_devices(seeds)), status=status,
                   message=message,
                   non_finite_at_step=[position.non_finite.get(r) for r in range(seeds)])
    return RunResult(runner, metrics, points, status, message, position, summary)


def _non_finite(config: SACConfig, runner: RunnerState, seeds: int, position: Position,
                chunk_steps: Tuple[int, int], stop: bool) -> str:
    """After a chunk from environment step `chunk_steps[0]` to `chunk_steps[1]`: the message
    that ends the run if a seed's state has become non-finite and `stop`, else "" (recording
    the chunk's end for each such run in `position.non_finite` when not `stop`). It reads the
    updates' sticky per-seed codes (`RunnerState.non_finite`), one small fetch a chunk; a
    compiled check of the whole state here cost a cold `fast` run 0.3 s of compiling (median of
    7 alternated pairs, 2 CPU cores)."""
    codes = np.broadcast_to(jax.device_get(runner.non_finite), (seeds,))
    if not codes.any():
        return ""
    if stop:
        return "non-finite {} between environment steps {} and {}".format(
            non_finite_state(config, runner, seeds), *chunk_steps)
    for run in np.flatnonzero(codes):
        position.non_finite.setdefault(int(run), chunk_steps[1])
    return ""


def non_finite_state(config: SACConfig, runner: RunnerState, seeds: int) -> Optional[str]:
    """What went non-finite first in `runner` (of `seeds` runs), e.g. "log_alpha of seed 1",
    from its sticky per-seed codes (`RunnerState.non_finite`); None if every seed is finite."""
    codes = np.broadcast_to(jax.device_get(runner.non_finite), (seeds,))
    return non_finite_name(runner.sac, codes, non_finite_fields(config)) if codes.any() else None


def _run_metrics(config: SACConfig, runner: RunnerState, position: Position, points: int
                 ) -> Dict[str, np.ndarray]:
    """`RunResult.metrics`: the program's outputs, with `wall_s` (the training seconds at which
    the host reached each of the `points` points done, NaN after) and `steps_per_s`."""
    metrics = {k: np.asarray(v) for k, v in jax.device_get(runner.outputs).items()}
    walls = np.full(config.num_evals, np.nan)
    for p, step in enumerate(metrics["env_steps"][0, :points]):
        walls[p] = position.walls.get(int(step), np.nan)
    metrics["wall_s"] = np.broadcast_to(walls, metrics["eval_return"].shape).copy()
    metrics["steps_per_s"] = metrics["env_steps"] / metrics["wall_s"]
    return metrics


def run_summary(config: SACConfig, metrics: Dict[str, np.ndarray], points: int, position: Position,
                delivered_steps: np.ndarray, stopped: np.ndarray, model: memory.MemoryNeed
                ) -> dict:
    """summary.json's figures of a run: per seed, the last evaluation of the last actor
    (`eval_return`), the delivered actor's confirmed return (`delivered_return`) and the step
    and training seconds at which it was selected, and the step, training seconds and seconds
    from process start from which the delivered actor's kept score stayed at the solved return
    (`solved_at`; None where it is not there at the end); for all seeds, the training and
    process seconds until the last of them was solved (None unless all were); the peak memory
    measured and `model`'s estimate of it (`sac_jax.memory`)."""
    threshold = envs.spec(config.env).solved_return
    steps = metrics["env_steps"][0, :points]
    before_training = position.startup_s + position.compile_s
    walls = {k: round(v, 3) for k, v in position.walls.items()}
    wall = lambda step: walls.get(step)
    process = lambda step: None if wall(step) is None else round(before_training + wall(step), 3)
    last = lambda name: [float(r) for r in metrics[name][:, points - 1]] if points else []
    selected = [int(s) if s >= 0 else None for s in np.ravel(delivered_steps)]
    solved = [solved_at(r, steps, threshold) if threshold is not None else None
              for r in metrics["delivered_return"][:, :points]]
    slowest = (None if not solved or None in solved
               else max(solved, key=lambda s: position.walls[s]))
    return {
        "env": config.env,
        "total_steps": int(steps[-1]) if points else 0,
        "eval_return": last("eval_return"),
        "delivered_return": last("delivered_return"),
        "delivered_at_step": selected,
        "delivered_wall_s": [wall(s) for s in selected],
        "solved_threshold": threshold,
        "solved_at_step": solved,
        "solved_wall_s": [wall(s) for s in solved],
        "solved_process_s": [process(s) for s in solved],
        "all_solved_wall_s": wall(slowest),
        "all_solved_process_s": process(slowest),
        "stopped": [bool(x) for x in np.ravel(stopped)],
        "peak_host_bytes": memory.peak_resident(),
        "peak_device_bytes": (jax.local_devices()[0].memory_stats() or {}).get(
            "peak_bytes_in_use"),
        "memory_model_peak_bytes": model.peak,
        "memory_model": dataclasses.asdict(model),
        "startup_s": round(position.startup_s, 3),
        "compile_s": round(position.compile_s, 3),
        "run_s": round(position.run_s, 3),
        "host_s": round(position.host_s, 3),
        "wall_s": round(position.compile_s + position.run_s, 3),
    }
