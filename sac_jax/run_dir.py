"""The run directory: what a training run leaves on disk, every file complete or absent.

    config.json        the SACConfig
    run.json           `RunInfo`: preset, seeds, seed, swept settings (what else `--resume`
                       needs to rebuild the program)
    checkpoints/<step>/ the whole vmapped training state at environment step <step>, buffers
                       and keys included, with the host loop's position and clocks: the newest
                       two, in orbax's format (`sac_jax.run_checkpoint`, `sac_jax.checkpoint`)
    metrics.csv        one row per evaluation point and seed       (`sac_jax.metric_writers`)
    summary.json       final figures (`sac_jax.run.RunResult.summary`) and the run's status
    tensorboard/       TensorBoard event files (the `tensorboard` package's writer), live
    curves.png         evaluation return vs environment steps      (`sac_jax.plots`)

This module makes the directory and reads back what defines the run; the modules named above
write the rest.
The directory is created under a temporary name and renamed, so an existing directory is never
written into by a new run; every later file is written to a temporary name and renamed, but
TensorBoard's event file, appended to as the run goes (`sac_jax.metric_writers`).
"""

from __future__ import annotations

import dataclasses
import functools
import json
import os
import shutil
import tempfile
from typing import Dict, List, Optional, Tuple

import jax

from envs import _lean_import
from sac_jax import compilation_cache, hyperparams, program_cache
from sac_jax.config import SACConfig
from sac_jax.train import SEED_AXES, RunnerState, make_train_parts
from sac_jax.whole_file import write_file, write_json


class RunDirError(ValueError):
    """A run directory that cannot be created or read back."""


@dataclasses.dataclass(frozen=True)
class RunInfo:
    """run.json: what besides the config defines a run. `seeds` keys are split from `seed`;
    a sweep (`sac_jax.hyperparams.sweep`) trains them for each of its `settings`
    ({field: [value per setting]}), all `runs` = seeds x settings in one program."""

    preset: str
    seeds: int
    seed: int
    settings: Optional[Dict[str, List[float]]] = None

    @property
    def runs(self) -> int:
        return self.seeds * (len(next(iter(self.settings.values()))) if self.settings else 1)

    def to_json(self) -> dict:
        info = {"preset": self.preset, "seeds": self.seeds, "seed": self.seed}
        return dict(info, settings=self.settings) if self.settings else info


def check_new(out: str) -> None:
    """`RunDirError` (one line) if `out` exists: a new run or sweep writes nothing into it."""
    if os.path.exists(out):
        raise RunDirError(f"--out={out}: already exists; choose a new directory")


def create_directory(out: str, files: Dict[str, object]) -> None:
    """Creates the directory `out` holding the JSON `files` {name: object}: made under a
    temporary name and renamed, so it is whole or absent. Raises `RunDirError` (one line) if
    `out` exists (nothing in it is touched) or cannot be created or written."""
    check_new(out)
    parent = os.path.dirname(os.path.abspath(out))
    if os.path.exists(parent) and not os.path.isdir(parent):
        raise RunDirError(f"--out={out}: {parent} is not a directory")
    try:
        os.makedirs(parent, exist_ok=True)
        tmp = tempfile.mkdtemp(prefix=".tmp-run-", dir=parent)
    except OSError as error:
        raise RunDirError(f"--out={out}: cannot be created ({error.strerror})") from None
    try:
        for name, obj in files.items():
            write_json(os.path.join(tmp, name), obj)
        os.rename(tmp, out)
    except OSError as error:  # e.g. a full disk: nothing is left behind
        shutil.rmtree(tmp, ignore_errors=True)
        raise RunDirError(f"--out={out}: cannot be written ({error.strerror})") from None
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def create(out: str, config: SACConfig, preset: str, seeds: int, seed: int,
           settings: Optional[Dict[str, list]] = None) -> None:
    """Creates the run directory `out` holding config.json and run.json (with the swept
    `settings` of `sac_jax.run.run_training`, if any). Raises `RunDirError` if `out` exists
    (nothing in it is touched)."""
    info = RunInfo(preset, seeds, seed, settings)
    create_directory(out, {"config.json": dataclasses.asdict(config), "run.json": info.to_json()})


def stored_config(fields: dict) -> SACConfig:
    """The `SACConfig` a run or sweep directory's JSON `fields` describe; runs written before
    `stop_measurements` (run_checkpoint.LAYOUT < 3) stopped on one measurement."""
    return SACConfig(**dict({"stop_measurements": 1}, **fields))


def results_written(run_dir: str) -> bool:
    """Whether the run directory holds the result files of a finished run (its summary.json
    says "finished", `sac_jax.run.FINISHED`); a run killed after its last checkpoint has none
    yet."""
    try:
        with open(os.path.join(run_dir, "summary.json")) as f:
            return json.load(f).get("status") == "finished"
    except (OSError, ValueError, AttributeError):
        return False


def read_config(run_dir: str) -> Tuple[SACConfig, RunInfo]:
    """(config, run info) of an existing run directory; `RunDirError` if either is
    unreadable."""
    if not os.path.isdir(run_dir):
        raise RunDirError(f"{run_dir}: no such run directory")
    try:
        with open(os.path.join(run_dir, "config.json")) as f:
            config = stored_config(json.load(f))
        with open(os.path.join(run_dir, "run.json")) as f:
            info = json.load(f)
        settings = info.get("settings")
        hyperparams.sweep(config, settings, 1)  # validates them
        return config, RunInfo(str(info["preset"]), int(info["seeds"]), int(info["seed"]),
                               settings)
    except (OSError, ValueError, TypeError, KeyError) as error:
        raise RunDirError(f"{run_dir}: not a readable run directory ({error})") from None


def state_template(config: SACConfig, seeds: int, settings: Optional[Dict[str, list]] = None
                   ) -> RunnerState:
    """Shapes and dtypes of the vmapped training state of `seeds` seeds (of each of the swept
    `settings`' values, if any; nothing is computed). Kept per arguments, and on disk beside
    the traced programs while the compilation cache is on (`program_cache.cached_shapes`):
    tracing the state's constructor takes 1.2 s for a Playground task on 2 CPU cores, and a
    run needs the shapes before it compiles (`sac_jax.memory.check`) and again after."""
    return _state_template(config, seeds, None if settings is None else
                           tuple((name, tuple(values)) for name, values in settings.items()))


@functools.lru_cache(maxsize=4)
def _state_template(config: SACConfig, seeds: int, settings) -> RunnerState:
    def trace():
        configs, values = hyperparams.sweep(
            config, None if settings is None else {name: list(v) for name, v in settings}, seeds)
        init = jax.vmap(make_train_parts(configs[0]).init, out_axes=SEED_AXES)
        keys = jax.eval_shape(lambda: jax.random.split(jax.random.key(0), seeds * len(configs)))
        return jax.eval_shape(init, keys, *([values] if values else []))

    # the state's classes (MJX's, Playground's) imported as the environments import them
    return program_cache.cached_shapes(f"state {config!r} {seeds} {settings!r}", trace,
                                       compilation_cache.program_directory(),
                                       unpickling=lambda: _lean_import.mjx_import("torch"))
