"""A run's training state in its run directory (`checkpoints/<environment step>/`, orbax's
format through `sac_jax.checkpoint`): saved off the training's critical path, the filled replay
slots only, and read back bit for bit against the state of the run's own configuration.

    writer = CheckpointWriter(run_dir)          # run_training(on_checkpoint=writer.save)
    config, info, state, position = load_checkpoint(run_dir)        # the newest step
"""

from __future__ import annotations

import collections
import math
import os
import threading
import time
from typing import Callable, List, Optional, Tuple

import jax
import numpy as np

from sac_jax import checkpoint, legacy_checkpoint, memory
from sac_jax.background import BackgroundWrites
from sac_jax.config import SACConfig
from sac_jax.messages import os_reason
from sac_jax.position import Position
from sac_jax.run_dir import RunInfo, read_config, state_template
from sac_jax.train import RunnerState

CHECKPOINTS = "checkpoints"
LAYOUT = 3
"""The training state's layout, in each checkpoint's metadata ("layout"). 3 since
`SACConfig.stop_measurements` (2026-11-28: the `stopped` output); 2 since the paired selection
(2026-11-28: `Delivered.count`, the `kept_return` output, the kept actor's slots in
`eval_point.Pending`); a checkpoint without it holds layout 1. Earlier layouts are read into the
current one (`_stored_as`, `_from_layout`), so earlier runs' policies still load and their
runs resume (with `stop_measurements` 1, the rule they ran under: `run_dir.read_config`)."""
MIN_INTERVAL_S = 5.0
"""`CheckpointWriter` starts a write at most this often."""


class CheckpointWriteError(OSError):
    """A checkpoint that could not be written (e.g. a full disk); the earlier ones are intact."""


def directory(run_dir: str) -> str:
    return os.path.join(run_dir, CHECKPOINTS)


def saved_steps(run_dir: str) -> List[int]:
    """Environment steps of the run's complete checkpoints, oldest first."""
    return checkpoint.steps(directory(run_dir))


def _buffer_filled_to(runner: RunnerState, filled: int) -> RunnerState:
    """`runner` with each seed's replay arrays (seeds, C, ...) cut to their first `filled` slots
    (arrays or shapes)."""
    cut = lambda x: (jax.ShapeDtypeStruct((x.shape[0], filled) + x.shape[2:], x.dtype)
                     if isinstance(x, jax.ShapeDtypeStruct) else x[:, :filled])
    data = jax.tree_util.tree_map(cut, runner.buffer.data)
    return runner.replace(buffer=runner.buffer.replace(data=data))


def _filled(runner: RunnerState) -> int:
    """The replay slots filled (the seeds train in lock-step: one size)."""
    return int(np.max(jax.device_get(runner.buffer.size)))


def _host_replay(data, filled: int):
    """The replay arrays (seeds, C, ...) cut to their first `filled` slots on the host: each
    device's shard fetched as a view (the host's memory, on a CPU), cut, and the shards of a
    seed axis split over several devices joined into one new array. (`jax.device_get` of a
    split array assembles all C slots: 64 seeds of 200,000 slots over 2 CPU devices peaked
    at 1,901 MB that way, against 1,446 MB on one device.)"""
    def fetch(x):
        if not isinstance(x, jax.Array):  # host arrays already (a loaded state)
            return np.asarray(x)[:, :filled]
        shards = {}
        for shard in x.addressable_shards:  # one per device; replicas share an index
            shards.setdefault(shard.index[0].start or 0, shard)
        views = [np.asarray(shards[start].data)[:, :filled] for start in sorted(shards)]
        return views[0] if len(views) == 1 else np.concatenate(views)
    return jax.tree_util.tree_map(fetch, data)


def _stored(runner: RunnerState, copy: bool = True) -> Tuple[list, int]:
    """(`checkpoint.to_host` leaves of the state to store, copies unless not `copy`; filled
    replay slots). A ring buffer fills its slots in order from slot 0 and the rest stay zero,
    so only the filled slots [0, size) of the replay buffers are stored, cut on the host (on
    the device, a slice of a new length compiles a new program each time)."""
    filled = _filled(runner)
    data = _host_replay(runner.buffer.data, filled)
    leaves = checkpoint.to_host(runner.replace(buffer=runner.buffer.replace(data=data)), False)
    if copy:  # the joined arrays are copies already
        joined = {id(x) for x in jax.tree_util.tree_leaves(data) if x.base is None}
        leaves = [x if id(x) in joined else np.array(x) for x in leaves]
    return leaves, filled


def _copy_bytes(runner: RunnerState) -> int:
    """Bytes of `_stored`'s copy of `runner`: the state with its filled replay slots."""
    filled, capacity = _filled(runner), runner.buffer.data.obs.shape[1]
    replay = memory.tree_bytes(runner.buffer.data)
    rest = memory.tree_bytes(runner) - replay
    return rest + replay * filled // capacity


def _device_copy(runner: RunnerState) -> RunnerState:
    """A copy of `runner` in new device buffers, its replay arrays (seeds, C, ...) cut on the
    device to their first `memory.stored_slots` slots (which hold the filled ones): the next
    chunk, which takes over the state's own buffers, leaves it as it is."""
    capacity = runner.buffer.data.obs.shape[1]
    slots = memory.stored_slots(_filled(runner), capacity, "accelerator")
    data = runner.buffer.data
    data = (jax.tree_util.tree_map(lambda x: x[:, :slots], data) if slots < capacity
            else jax.device_put(data, may_alias=False))  # a slice is a new buffer already
    rest = jax.device_put(runner.replace(buffer=runner.buffer.replace(data=None)),
                          may_alias=False)
    return rest.replace(buffer=rest.buffer.replace(data=data))


def _write(run_dir: str, leaves: list, filled: int, position: Position) -> None:
    """Writes checkpoint step `position.env_steps`; `CheckpointWriteError` (one line) if it
    cannot be written, leaving the earlier steps and no partial one."""
    where = directory(run_dir)
    try:
        checkpoint.save(where, position.env_steps, leaves,
                        {"position": position.to_json(), "buffer_filled": filled,
                         "layout": LAYOUT})
    except Exception as error:  # OSError, or tensorstore's ValueError naming the OS error
        checkpoint.remove_partial(where)
        raise CheckpointWriteError(f"checkpoint of step {position.env_steps} in {where} "
                                   f"could not be written ({os_reason(error)})") from None


def save_checkpoint(run_dir: str, runner: RunnerState, position: Position) -> None:
    """Saves the training state and the host loop's `position` (environment steps, chunks done,
    clocks) as checkpoint step `position.env_steps`."""
    _write(run_dir, *_stored(runner), position)


def _room_for_copy(runner: RunnerState) -> bool:
    """Whether every device holding part of `runner` has free memory for twice its part of
    `_device_copy(runner)` (`memory.copy_fits`: a copy, and as much again left for the next
    chunk). True where the backend reports no memory limit (the CPU, whose device memory is
    the host's)."""
    capacity = runner.buffer.data.obs.shape[1]
    kept = memory.stored_slots(_filled(runner), capacity, "accelerator") / capacity
    replay = {id(leaf) for leaf in jax.tree_util.tree_leaves(runner.buffer.data)}
    need = collections.Counter()
    for leaf in jax.tree_util.tree_leaves(runner):
        if not isinstance(leaf, jax.Array):
            continue  # host memory
        shard = leaf.nbytes * math.prod(leaf.sharding.shard_shape(leaf.shape)) // max(
            1, math.prod(leaf.shape))
        for device in leaf.sharding.addressable_devices:
            need[device] += int(shard * kept) if id(leaf) in replay else shard
    for device, nbytes in need.items():
        stats = device.memory_stats() or {}
        if "bytes_limit" in stats and not memory.copy_fits(
                nbytes, stats["bytes_limit"] - stats["bytes_in_use"]):
            return False
    return True


def _on_host(tree) -> bool:
    """Whether every device array of `tree` lives on CPU devices, whose memory is the host's:
    fetching it there (`jax.device_get`) is a view, not a copy."""
    return all(device.platform == "cpu" for leaf in jax.tree_util.tree_leaves(tree)
               if isinstance(leaf, jax.Array) for device in leaf.sharding.device_set)


class CheckpointWriter(BackgroundWrites):
    """`save_checkpoint` off the training's critical path. `save(runner, position)` only queues
    a copy of the state in new device buffers (`_device_copy`: the replay slots filled so far,
    cut on the device, and the rest by `jax.device_put(..., may_alias=False)`; the next chunk
    may then take over the state's own) and returns; the
    background thread copies it to host memory and writes it while the device trains on. When saves
    come faster than writes, the thread writes the newest state saved and skips the older ones
    waiting. A device without room for the copy (`_room_for_copy`) gets none: `save` then waits for
    the writes under way, whose copies it frees, and fetches the state to host memory in line; so
    does a state whose copy is at most `memory.IN_LINE_COPY_BYTES`, without waiting (a millisecond's
    fetch, where a device copy would be held beside the next chunk). (H100, 256 seeds of the `fast`
    preset: saving in line cost 8.6 s of a 19.4 s run; copying to the host in line still 1.8-2.0 s
    of an 11.5 s run, BENCHMARKS.md.) A state on
    the CPU is always fetched in line: there the fetch is a view, and the copy the checkpoint
    keeps holds the filled replay slots only, where a device copy would hold every slot; where
    host memory has no room for that copy (`sac_jax.memory.copy_fits`), the state is written
    in line from the view, with no copy. A write that fails raises `CheckpointWriteError` from
    the next `save` or from `close` (from `save` itself, written in line).

    A state is saved at most every `min_interval_s` seconds (the first that long after the
    writer is made), and always where the run ends (`position.ends_run`: its last point, or
    a stop); a save in between returns at once, copying nothing. A kill loses at most that
    much training; a stop (Ctrl-C, the end) loses nothing. An orbax step costs about 0.06 s
    of CPU on 2 cores; written at every evaluation point of the `fast` preset (one every
    0.6 s) it slowed the run by 40%.
    """

    def __init__(self, run_dir: str, min_interval_s: Optional[float] = None):
        super().__init__()
        self._run_dir = run_dir
        self._lock = threading.Lock()
        self._newest: Optional[Callable[[], None]] = None
        self._min_interval_s = MIN_INTERVAL_S if min_interval_s is None else min_interval_s
        self._last_start = time.perf_counter()
        self.submit(checkpoint.prepare)  # imports orbax while the run compiles

    def _write_newest(self) -> None:
        with self._lock:
            write, self._newest = self._newest, None
        if write is not None:
            write()

    def save(self, runner: RunnerState, position: Position) -> None:
        due = time.perf_counter() - self._last_start >= self._min_interval_s
        if not (due or position.ends_run):
            return
        self._last_start = time.perf_counter()
        position = position.copy()
        on_host = _on_host(runner)
        small = not on_host and _copy_bytes(runner) <= memory.IN_LINE_COPY_BYTES
        if not on_host and not small and _room_for_copy(runner):
            state = _device_copy(runner)
            write = lambda: save_checkpoint(self._run_dir, state, position)
        else:
            if not small:  # one host copy at a time: none being written, the one waiting dropped
                self._collect(wait=True)
                with self._lock:
                    self._newest = None
            if on_host and not memory.copy_fits(_copy_bytes(runner), memory.available()[0]):
                _write(self._run_dir, *_stored(runner, copy=False), position)  # in line
                return
            leaves, filled = _stored(runner)
            write = lambda: _write(self._run_dir, leaves, filled, position)
        with self._lock:
            self._newest = write
        self.submit(self._write_newest)


def _layout_1(template: RunnerState) -> RunnerState:
    """The shapes of `template` (layout 2) as layout 1 stored them: no kept-score count, no
    `kept_return` output, and with `eval_alongside` one actor and E episodes per slot (axis 1
    of the pending arrays, after the seeds') instead of two and 2 E."""
    pending = template.pending
    if pending is not None:
        half = lambda x: jax.ShapeDtypeStruct((x.shape[0], x.shape[1] // 2) + x.shape[2:],
                                              x.dtype)
        pending = pending.replace(
            actor_params=jax.tree_util.tree_map(half, pending.actor_params), kept_steps=None,
            episodes=type(pending.episodes)(*jax.tree_util.tree_map(half, pending.episodes[:4]),
                                            pending.episodes.steps))
    delivered = template.delivered
    return template.replace(
        delivered=None if delivered is None else delivered.replace(count=None), pending=pending,
        outputs={name: x for name, x in template.outputs.items() if name != "kept_return"})


def _from_layout_1(runner: RunnerState) -> RunnerState:
    """A state read in layout 1 (`_layout_1`) in layout 2: a kept actor's score counts as one
    measurement (it was one confirmation); no kept actor's returns before; the evaluations under
    way measured no kept actor, so their kept slots (its actor, its episodes ended) count for
    nothing (`kept_steps` -2, no actor's `env_steps`)."""
    outputs = dict(runner.outputs, kept_return=np.full_like(runner.outputs["confirm_return"],
                                                            np.nan))
    delivered = runner.delivered
    if delivered is not None:
        delivered = delivered.replace(count=(np.asarray(delivered.env_steps) >= 0).astype(np.int32))
    pending = runner.pending
    if pending is not None:
        n, slots = pending.env_steps.shape
        def pair(old, kept):  # (N, D, ...) and the kept slots' (N, D, ...) -> (N, 2 D, ...)
            return np.stack([old, kept], axis=2).reshape((n, 2 * slots) + old.shape[2:])
        by_slot = lambda x: np.asarray(x).reshape((n, slots, -1) + x.shape[2:])
        episodes = pending.episodes
        rows = lambda x: pair(by_slot(x), by_slot(x)).reshape((n, -1) + x.shape[2:])
        start, states = (jax.tree_util.tree_map(rows, tree) for tree in episodes[:2])
        alive = by_slot(episodes.alive)
        kept_actor = jax.tree_util.tree_map(
            lambda p, k: np.broadcast_to(np.asarray(k)[:, None], p.shape), pending.actor_params,
            delivered.actor_params)
        pending = pending.replace(
            actor_params=jax.tree_util.tree_map(pair, pending.actor_params, kept_actor),
            episodes=type(episodes)(start, states,
                                    pair(alive, np.zeros_like(alive)).reshape(n, -1),
                                    pair(by_slot(episodes.returns),
                                         by_slot(episodes.returns)).reshape(n, -1),
                                    episodes.steps),
            kept_steps=np.full((n, slots), -2, np.int32))
    return runner.replace(outputs=outputs, delivered=delivered, pending=pending)


def _stored_as(template: RunnerState, layout: int) -> RunnerState:
    """The shapes of `template` (the current layout) as layout `layout` stored them: before
    layout 3 without the `stopped` output."""
    if layout < 3:
        template = template.replace(outputs={name: x for name, x in template.outputs.items()
                                             if name != "stopped"})
    return _layout_1(template) if layout == 1 else template


def _from_layout(runner: RunnerState, layout: int, config: SACConfig) -> RunnerState:
    """A state read in layout `layout` (`_stored_as`) in the current one. Before layout 3 a seed
    stopped where its kept score reached `config.stop_at` (one measurement sufficed), and its
    kept score stayed fixed from then on: its `stopped` output is that comparison (float32, as
    the program made it), NaN at points not yet done."""
    if layout == 1:
        runner = _from_layout_1(runner)
    if layout < 3:
        delivered = np.asarray(runner.outputs["delivered_return"], np.float32)
        stopped = (delivered >= np.float32(config.stop_at) if config.stop_when_solved
                   else np.zeros(delivered.shape, bool))
        runner = runner.replace(outputs=dict(runner.outputs, stopped=np.where(
            np.isnan(delivered), np.nan, stopped).astype(np.float32)))
    return runner


def load_checkpoint(run_dir: str, step: Optional[int] = None, earlier: bool = False
                    ) -> Tuple[SACConfig, RunInfo, RunnerState, Position]:
    """(config, run info, training state, position) of the run directory's checkpoint of
    environment step `step` (default: the newest); `RunDirError` or its subclass
    `checkpoint.CheckpointError` says what is wrong. A damaged newest checkpoint is refused,
    and the message names an intact earlier step, if any, to continue from. A run
    directory of an earlier sac-jax (`legacy_checkpoint`) is read too; one whose state kept
    no delivered actor is refused unless `earlier`: then its state comes with `delivered`
    and `stopped` None."""
    config, info = read_config(run_dir)
    template = state_template(config, info.seeds, info.settings)
    legacy = os.path.join(run_dir, legacy_checkpoint.FILE)

    def stored(meta):
        Position.from_json(meta["position"])  # a bad one is "unexpected metadata"
        filled = meta["buffer_filled"]
        if isinstance(filled, bool) or not isinstance(filled, int) or not (
                0 <= filled <= config.buffer_size):
            raise ValueError(f"buffer_filled={filled!r} outside [0, {config.buffer_size}]")
        state = _stored_as(template, meta.get("layout", 1))
        if meta.get("format") == 2:  # a legacy file without the delivered actor
            if not earlier:
                raise checkpoint.CheckpointError(
                    f"checkpoint {legacy}: written by an earlier sac-jax (format 2) that kept no "
                    "delivered policy; it cannot be resumed, train anew")
            return _buffer_filled_to(state.replace(delivered=None, stopped=None,
                                                   non_finite=None), filled)
        if meta.get("format") == 3:  # legacy files hold no non-finite code: finite then
            return _buffer_filled_to(state.replace(non_finite=None), filled)
        return _buffer_filled_to(state, filled)

    if not os.path.isdir(directory(run_dir)) and os.path.exists(legacy):
        runner, meta = legacy_checkpoint.load(legacy, stored)
        runner = _from_layout(
            runner.replace(non_finite=np.zeros(template.non_finite.shape, np.int32)), 1, config)
        return (config, info, _padded(runner, config.buffer_size),
                Position.from_json(meta["position"]))
    try:
        runner, meta, _ = checkpoint.load(directory(run_dir), stored, step)
    except checkpoint.CheckpointError as error:
        intact = _intact_before(run_dir, stored) if step is None else None
        if intact is None:
            raise
        raise checkpoint.CheckpointError(
            f"{error}; the checkpoint of step {intact} before it is intact: continue from it "
            f"with scripts/train.py --resume {run_dir} --resume-step {intact}") from None
    runner = _from_layout(runner, meta.get("layout", 1), config)
    return (config, info, _padded(runner, config.buffer_size),
            Position.from_json(meta["position"]))


def _intact_before(run_dir: str, template) -> Optional[int]:
    """The newest step, short of the newest, that loads without error; None if none does."""
    for step in reversed(saved_steps(run_dir)[:-1]):
        try:
            checkpoint.load(directory(run_dir), template, step)
            return step
        except checkpoint.CheckpointError:
            continue
    return None


def _padded(runner: RunnerState, capacity: int) -> RunnerState:
    """`runner` with its replay arrays zero-padded back to `capacity` slots."""
    pad = lambda x: np.concatenate(
        [x, np.zeros((x.shape[0], capacity - x.shape[1]) + x.shape[2:], x.dtype)], axis=1)
    data = jax.tree_util.tree_map(pad, runner.buffer.data)
    return runner.replace(buffer=runner.buffer.replace(data=data))
