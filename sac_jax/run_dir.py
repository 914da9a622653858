"""The run directory: what a training run leaves on disk, every file complete or absent.

    config.json        the SACConfig
    run.json           preset, seeds, seed (what else `--resume` needs to rebuild the program)
    checkpoint.msgpack the whole vmapped training state, buffers and keys included
                       (`sac_jax.checkpoint`), with the host loop's position and clocks
    metrics.csv        one row per evaluation point and seed
    summary.json       final figures (`sac_jax.run.RunResult.summary`) and the run's status
    curves.png         evaluation return vs environment steps: mean over seeds, min-max band
    tensorboard/       TensorBoard event files (the `tensorboard` package's writer)

The directory is created under a temporary name and renamed, so an existing directory is never
written into by a new run; every later file is written to a temporary name and renamed.
"""

from __future__ import annotations

import collections
import copy
import dataclasses
import json
import math
import os
import shutil
import tempfile
import threading
from typing import Callable, Dict, Optional, Tuple

import jax
import numpy as np

from sac_jax import checkpoint, hyperparams
from sac_jax.background import BackgroundWrites
from sac_jax.config import SACConfig
from sac_jax.train import SEED_AXES, RunnerState, make_train_parts

CHECKPOINT = "checkpoint.msgpack"


class RunDirError(ValueError):
    """A run directory that cannot be created or read back."""


def write_file(path: str, data: bytes) -> None:
    """Writes `data` to `path` under a temporary name, then renames it: whole or absent."""
    tmp = f"{path}.tmp-{os.getpid()}"
    with open(tmp, "wb") as f:
        f.write(data)
    os.replace(tmp, path)


def write_json(path: str, obj) -> None:
    write_file(path, (json.dumps(obj, indent=2) + "\n").encode())


def create_directory(out: str, files: Dict[str, object]) -> None:
    """Creates the directory `out` holding the JSON `files` {name: object}: made under a
    temporary name and renamed, so it is whole or absent. Raises `RunDirError` (one line) if
    `out` exists (nothing in it is touched) or cannot be created or written."""
    if os.path.exists(out):
        raise RunDirError(f"--out={out}: already exists; choose a new directory")
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
    info = {"preset": preset, "seeds": seeds, "seed": seed}
    create_directory(out, {"config.json": dataclasses.asdict(config),
                           "run.json": dict(info, settings=settings) if settings else info})


def read_config(run_dir: str) -> Tuple[SACConfig, dict]:
    """(config, run info: preset, seeds, seed, settings (None if not swept), runs (seeds x
    settings)) of an existing run directory; `RunDirError` if either is unreadable."""
    if not os.path.isdir(run_dir):
        raise RunDirError(f"{run_dir}: no such run directory")
    try:
        with open(os.path.join(run_dir, "config.json")) as f:
            config = SACConfig(**json.load(f))
        with open(os.path.join(run_dir, "run.json")) as f:
            info = json.load(f)
        settings = info.get("settings")
        configs, _ = hyperparams.sweep(config, settings, 1)  # validates them
        return config, {"preset": str(info["preset"]), "seeds": int(info["seeds"]),
                        "seed": int(info["seed"]), "settings": settings,
                        "runs": int(info["seeds"]) * len(configs)}
    except (OSError, ValueError, TypeError, KeyError) as error:
        raise RunDirError(f"{run_dir}: not a readable run directory ({error})") from None


def state_template(config: SACConfig, seeds: int, settings: Optional[Dict[str, list]] = None
                   ) -> RunnerState:
    """Shapes and dtypes of the vmapped training state of `seeds` seeds (of each of the swept
    `settings`' values, if any; nothing is computed)."""
    configs, values = hyperparams.sweep(config, settings, seeds)
    init = jax.vmap(make_train_parts(configs[0]).init, out_axes=SEED_AXES)
    keys = jax.random.split(jax.random.key(0), seeds * len(configs))
    return jax.eval_shape(init, keys, *([values] if values else []))


def _buffer_filled_to(runner: RunnerState, filled: int) -> RunnerState:
    """`runner` with each seed's replay arrays (seeds, C, ...) cut to their first `filled` slots
    (arrays or shapes)."""
    cut = lambda x: (jax.ShapeDtypeStruct((x.shape[0], filled) + x.shape[2:], x.dtype)
                     if isinstance(x, jax.ShapeDtypeStruct) else x[:, :filled])
    data = jax.tree_util.tree_map(cut, runner.buffer.data)
    return runner.replace(buffer=runner.buffer.replace(data=data))


def _checkpoint_leaves(runner: RunnerState) -> Tuple[list, int]:
    """(`checkpoint.to_host` leaves of the state to store, filled replay slots). A ring buffer
    fills its slots in order from slot 0 and the rest stay zero, so only the filled slots
    [0, size) of the replay buffers are stored (the seeds train in lock-step: one size)."""
    filled = int(np.max(jax.device_get(runner.buffer.size)))
    # cut on the host: on the device, a slice of a new length compiles a new program each time
    runner = runner.replace(buffer=jax.device_get(runner.buffer))
    return checkpoint.to_host(_buffer_filled_to(runner, filled)), filled


def _write_leaves(run_dir: str, leaves: list, filled: int, position: dict) -> None:
    checkpoint.save(os.path.join(run_dir, CHECKPOINT), leaves,
                    {"position": position, "buffer_filled": filled})


def save_checkpoint(run_dir: str, runner: RunnerState, position: dict) -> None:
    """Saves the training state and the host loop's `position` (chunks done, clocks)."""
    _write_leaves(run_dir, *_checkpoint_leaves(runner), position)


def _room_for_copy(tree) -> bool:
    """Whether every device holding part of `tree` has free memory for twice that part: a copy,
    and as much again left for the next chunk. True where the backend reports no memory limit
    (the CPU, whose device memory is the host's)."""
    need = collections.Counter()
    for leaf in jax.tree_util.tree_leaves(tree):
        if not isinstance(leaf, jax.Array):
            continue  # host memory
        shard = leaf.nbytes * math.prod(leaf.sharding.shard_shape(leaf.shape)) // max(
            1, math.prod(leaf.shape))
        for device in leaf.sharding.addressable_devices:
            need[device] += shard
    for device, nbytes in need.items():
        stats = device.memory_stats() or {}
        if "bytes_limit" in stats and stats["bytes_limit"] - stats["bytes_in_use"] < 2 * nbytes:
            return False
    return True


def _on_host(tree) -> bool:
    """Whether every device array of `tree` lives on CPU devices, whose memory is the host's:
    fetching it there (`jax.device_get`) is a view, not a copy."""
    return all(device.platform == "cpu" for leaf in jax.tree_util.tree_leaves(tree)
               if isinstance(leaf, jax.Array) for device in leaf.sharding.device_set)


class CheckpointWriter(BackgroundWrites):
    """`save_checkpoint` off the training's critical path. `save(runner, position)` only queues
    a copy of the state in new device buffers (`jax.device_put(..., may_alias=False)`, which
    compiles nothing; the next chunk may then take over the state's own) and returns; the
    background thread copies it to host memory, serialises and writes it while the device
    trains on. When saves come faster than writes, the thread writes the newest state saved and
    skips the older ones waiting: the file always holds a whole state, the newest one written.
    A device without room for the copy (`_room_for_copy`) gets none: `save` then waits for the
    writes under way, whose copies it frees, and fetches the state to host memory in line.
    (H100, 256 seeds of the `fast` preset: saving in line cost 8.6 s of a 19.4 s run; copying
    to the host in line still 1.8-2.0 s of an 11.5 s run, BENCHMARKS.md.) A state on the CPU
    is always fetched in line: there the fetch is a view, and the copy the checkpoint keeps holds
    the filled replay slots only, where a device copy would hold every slot (`sac_jax.memory`).
    """

    def __init__(self, run_dir: str):
        super().__init__()
        self._run_dir = run_dir
        self._lock = threading.Lock()
        self._newest: Optional[Callable[[], None]] = None

    def _write_newest(self) -> None:
        with self._lock:
            write, self._newest = self._newest, None
        if write is not None:
            write()

    def save(self, runner: RunnerState, position: dict) -> None:
        position = copy.deepcopy(position)
        if not _on_host(runner) and _room_for_copy(runner):
            state = jax.device_put(runner, may_alias=False)
            write = lambda: save_checkpoint(self._run_dir, state, position)
        else:
            self._collect(wait=True)
            leaves, filled = _checkpoint_leaves(runner)
            write = lambda: _write_leaves(self._run_dir, leaves, filled, position)
        with self._lock:
            self._newest = write
        self.submit(self._write_newest)


def load_checkpoint(run_dir: str, earlier: bool = False
                    ) -> Tuple[SACConfig, dict, RunnerState, dict]:
    """(config, run info, training state, position) of a run directory's checkpoint;
    `RunDirError` (or its subclass `checkpoint.CheckpointError`) says what is wrong. A
    checkpoint of an earlier sac-jax (format 2, which kept no delivered actor) is refused,
    unless `earlier`: then its state comes with `delivered` and `stopped` None."""
    config, info = read_config(run_dir)
    template = state_template(config, info["seeds"], info["settings"])
    capacity = config.buffer_size
    path = os.path.join(run_dir, CHECKPOINT)

    def stored(meta):
        filled = meta["buffer_filled"]
        if isinstance(filled, bool) or not isinstance(filled, int) or not 0 <= filled <= capacity:
            raise ValueError(f"buffer_filled={filled!r} outside [0, {capacity}]")
        if meta["format"] != checkpoint.FORMAT:
            if not earlier:
                raise checkpoint.CheckpointError(
                    f"checkpoint {path}: written by an earlier sac-jax (format {meta['format']}) "
                    "that kept no delivered policy; it cannot be resumed, train anew")
            return _buffer_filled_to(template.replace(delivered=None, stopped=None), filled)
        return _buffer_filled_to(template, filled)

    runner, meta = checkpoint.load(path, stored)
    pad = lambda x: np.concatenate(
        [x, np.zeros((x.shape[0], capacity - x.shape[1]) + x.shape[2:], x.dtype)], axis=1)
    data = jax.tree_util.tree_map(pad, runner.buffer.data)
    return config, info, runner.replace(buffer=runner.buffer.replace(data=data)), meta["position"]
