"""Checkpoints of a pytree of arrays (PRNG keys included) with orbax-checkpoint, the format of
Brax and MuJoCo Playground, each array checked against a CRC-32 of its bytes on load.

A checkpoint directory holds numbered steps, the newest `KEEP` of them (orbax's
`CheckpointManager`: each step is written under a temporary name and renamed when complete,
so a stopped process leaves the previous steps as they were):

    <directory>/<step>/state/   the arrays, orbax's `StandardSave` (tensorstore, never pickle)
    <directory>/<step>/meta/    JSON: {"format": FORMAT, "meta": caller's metadata,
                                       "leaves": [{"shape", "dtype", "crc32"} per leaf]}
    <directory>/<step>/state_sizes.json   {file under state/: its bytes}, written after orbax's
                                save: a data file cut short or extended is refused before
                                tensorstore reads it (its reads past a file's end fail on
                                background threads, which print tracebacks of their own)

Leaves are the `jax.tree_util` leaves of the saved pytree in order, stored as host arrays
named "0", "1", ...; a typed PRNG key array is stored as its `jax.random.key_data` and
wrapped again on load. Arrays with no elements, which orbax cannot store, are recreated from
their recorded shape. Loading checks every leaf's shape and dtype against a template
(`jax.eval_shape` of the state's constructor) before reading any data, so a checkpoint of
another configuration is refused, then each array's CRC-32 (`zlib.crc32`): bytes flipped in
the data files, which tensorstore may read back as other numbers, are refused too. Every
problem is a `CheckpointError` naming the checkpoint and the array.
"""

from __future__ import annotations

import errno
import glob
import json
import os
import shutil
import zlib
from typing import Any, Callable, List, Optional, Tuple, Union

import jax
import numpy as np

from sac_jax.whole_file import write_file

FORMAT = 4
"""Format 4 is this module's (orbax); formats 2 and 3 were single msgpack files of earlier
sac-jax (`sac_jax.legacy_checkpoint` reads them)."""
KEEP = 2
"""Steps kept: the newest and the one before it, to fall back on if the newest is damaged."""
PACKED_BYTES = 1 << 16
"""Arrays smaller than this are stored packed together (`_pack`)."""
ROOM_FOR_METADATA = 1 << 20
"""Bytes a step takes beyond its arrays' (orbax's metadata files: about 20 kB measured)."""
SIZES = "state_sizes.json"
"""A step's record of the byte sizes of its files under state/ (module docstring)."""


class CheckpointError(ValueError):
    """A checkpoint that is missing, unreadable, damaged, or does not fit the expected state."""


def _is_key(leaf) -> bool:
    return jax.dtypes.issubdtype(leaf.dtype, jax.dtypes.prng_key)


def to_host(tree: Any, copy: bool = True) -> List[np.ndarray]:
    """The leaves of `tree` as `save` stores them: numpy arrays of their own (copies: on a CPU
    a fetched array may share memory with a device buffer that a later donation reuses; not
    `copy`, views where the device's memory is the host's, for a save before the state changes
    again), PRNG keys as their key data. `save(d, s, to_host(tree), meta)` stores what
    `save(d, s, tree, meta)` does."""
    leaves = [jax.random.key_data(x) if _is_key(x) else x for x in jax.tree_util.tree_leaves(tree)]
    return [np.array(x) if copy else np.asarray(x) for x in jax.device_get(leaves)]


def _crc32(array: np.ndarray) -> int:
    return zlib.crc32(np.ascontiguousarray(array).view(np.uint8).reshape(-1))


def _ocp():
    """orbax.checkpoint, imported when first needed (0.3-1.8 s on the CPU)."""
    import orbax.checkpoint as ocp
    return ocp


def prepare() -> None:
    """Imports what `save` needs; `run_checkpoint.CheckpointWriter` does it on its background
    thread while the run compiles."""
    _ocp()


def _manager(directory: str, create: bool):
    ocp = _ocp()
    options = ocp.CheckpointManagerOptions(max_to_keep=KEEP, create=create,
                                           enable_async_checkpointing=False)
    return ocp.CheckpointManager(os.path.abspath(directory), options=options)


def save(directory: str, step: int, tree: Any, meta: dict) -> None:
    """Writes `tree` (a pytree of arrays, or `to_host`'s leaves, stored as they are: no further
    copy of a state's replay data) and the JSON-able `meta` as
    step `step` of the checkpoint directory `directory` (created if missing), keeping the
    newest `KEEP` steps. A step already there, and any after it, are removed first: a run
    resumed from an earlier step continues from there, and orbax writes only steps after its
    newest. Synchronous: `CheckpointWriter`
    in `sac_jax.run_checkpoint` calls it off the training's critical path. A filesystem without
    room for the arrays' bytes (an upper bound: orbax may compress them) is refused before
    anything is written, with OSError(ENOSPC): orbax, failing part-way, leaves a half-written
    step and prints pages of tracebacks from its threads. A write that fails anyway raises
    (OSError, or tensorstore's ValueError) and leaves the earlier steps intact."""
    owned = isinstance(tree, list) and all(type(x) is np.ndarray for x in tree)
    leaves = tree if owned else to_host(tree)
    need = sum(x.nbytes for x in leaves) + ROOM_FOR_METADATA
    free = shutil.disk_usage(_existing_ancestor(directory)).free
    if free < need:
        raise OSError(errno.ENOSPC, f"{os.strerror(errno.ENOSPC)}: the checkpoint needs up to "
                                    f"{need / 1e6:.1f} MB, {free / 1e6:.1f} MB are free")
    records = [{"shape": list(x.shape), "dtype": x.dtype.name, "crc32": _crc32(x)}
               for x in leaves]
    arrays = _pack(leaves, records)
    ocp = _ocp()
    remove_partial(directory)
    with _manager(directory, create=True) as manager:
        for later in [s for s in manager.all_steps() if s >= step]:
            manager.delete(later)
        manager.save(step, args=ocp.args.Composite(
            state=ocp.args.StandardSave(arrays),
            meta=ocp.args.JsonSave({"format": FORMAT, "meta": meta, "leaves": records})))
    step_dir = os.path.join(directory, str(step))
    write_file(os.path.join(step_dir, SIZES), json.dumps(_state_sizes(step_dir)).encode())


def _state_sizes(step_dir: str) -> dict:
    """{path under `step_dir`/state: bytes} of every file there."""
    root = os.path.join(step_dir, "state")
    return {os.path.relpath(os.path.join(folder, name), root):
            os.path.getsize(os.path.join(folder, name))
            for folder, _, names in os.walk(root) for name in names}


def _check_sizes(where: str) -> None:
    """CheckpointError if a file under `where`/state differs in size from when it was written
    (nothing to check in a step written before `SIZES` was)."""
    path = os.path.join(where, SIZES)
    if not os.path.exists(path):
        return
    try:
        with open(path) as f:
            written = dict(json.load(f))
    except (OSError, ValueError, TypeError):
        raise CheckpointError(f"checkpoint {where}: unreadable ({SIZES})") from None
    now = _state_sizes(where)
    changed = sorted(name for name in written.keys() | now.keys()
                     if written.get(name) != now.get(name))
    if changed:
        raise CheckpointError(f"checkpoint {where}: damaged (state/{changed[0]} holds "
                              f"{now.get(changed[0], 'no')} bytes, {written.get(changed[0], 'no')} "
                              "when written)")


def _pack(leaves: List[np.ndarray], records: List[dict]) -> dict:
    """The arrays orbax stores: each leaf of `PACKED_BYTES` or more as array "<i>", the smaller
    ones concatenated, flat, into one array "packed_<dtype>" per dtype, their offsets noted in
    `records` ("packed": element offset). orbax's cost grows with the number of arrays: 1.3 ms
    each beyond 0.09 s a step (2-core CPU), so the 197 arrays of the `fast` preset's state took
    0.27 s a save, and its 5 replay arrays and 5 packed ones take 0.10 s."""
    arrays, packed = {}, {}
    for i, (x, record) in enumerate(zip(leaves, records)):
        if x.nbytes >= PACKED_BYTES:
            arrays[str(i)] = x
        else:
            parts = packed.setdefault(x.dtype.name, [])
            record["packed"] = sum(p.size for p in parts)
            parts.append(x.reshape(-1))
    arrays.update({f"packed_{dtype}": np.concatenate(parts) for dtype, parts in packed.items()
                   if sum(p.size for p in parts)})
    return arrays


def _layout(records: List[dict]) -> dict:
    """Zero arrays of the shapes and dtypes of the arrays `_pack` stored for `records`."""
    layout, packed = {}, {}
    for i, record in enumerate(records):
        shape, dtype = tuple(record["shape"]), np.dtype(record["dtype"])
        if "packed" in record:
            packed[dtype] = packed.get(dtype, 0) + int(np.prod(shape))
        elif np.prod(shape):
            layout[str(i)] = np.zeros(shape, dtype)
    layout.update({f"packed_{dtype.name}": np.zeros(size, dtype)
                   for dtype, size in packed.items() if size})
    return layout


def _unpack(arrays: dict, records: List[dict]) -> List[np.ndarray]:
    """The leaves `_pack` stored, in order (numpy; copies of their parts of a packed array)."""
    leaves = []
    for i, record in enumerate(records):
        shape, dtype = tuple(record["shape"]), np.dtype(record["dtype"])
        if "packed" not in record:
            leaves.append(np.asarray(arrays[str(i)]))
            continue
        size, start = int(np.prod(shape)), record["packed"]
        flat = np.asarray(arrays.get(f"packed_{dtype.name}", np.zeros(0, dtype)))
        leaves.append(flat[start:start + size].reshape(shape).copy())
    return leaves


def remove_partial(directory: str) -> None:
    """Removes the steps orbax left half-written in `directory` (`<step>.orbax-checkpoint-tmp`,
    from a process killed while writing, or a failed write). `save` does it first; orbax's own
    option for it removes them on a thread of every manager opened, which races with another
    manager's doing the same."""
    for partial in glob.glob(os.path.join(glob.escape(directory), "*.orbax-checkpoint-tmp*")):
        shutil.rmtree(partial, ignore_errors=True)


def expected_leaves(template, meta: dict, count: int, where: str):
    """(leaves, treedef) of `template` (a pytree, or a function of the stored `meta` returning
    one), which must have the `count` leaves the checkpoint `where` holds; CheckpointError
    otherwise."""
    if callable(template):
        try:
            template = template(meta)
        except CheckpointError:
            raise
        except (KeyError, TypeError, ValueError) as error:
            raise CheckpointError(f"checkpoint {where}: unexpected metadata ({error!r})") from None
    expected, treedef = jax.tree_util.tree_flatten(template)
    if count != len(expected):
        raise CheckpointError(f"checkpoint {where}: holds {count} arrays, this "
                              f"configuration has {len(expected)}")
    return expected, treedef


def _existing_ancestor(path: str) -> str:
    path = os.path.abspath(path)
    while not os.path.exists(path):
        path = os.path.dirname(path)
    return path


def steps(directory: str) -> List[int]:
    """The complete steps of the checkpoint directory `directory`, oldest first ([] if it
    does not exist)."""
    if not os.path.isdir(directory):
        return []
    with _manager(directory, create=False) as manager:
        return sorted(manager.all_steps())


def load(directory: str, template: Union[Any, Callable[[dict], Any]], step: Optional[int] = None
         ) -> Tuple[Any, dict, int]:
    """Reads step `step` (default: the newest) of the checkpoint directory `directory` into the
    structure of `template` (a pytree of arrays or `jax.ShapeDtypeStruct`s, or a function of the
    stored meta returning one); returns (tree of numpy arrays and PRNG keys, meta, step).
    Raises `CheckpointError` naming the checkpoint and the problem."""
    available = steps(directory)
    if not available:
        raise CheckpointError(f"checkpoint {directory}: not found")
    step = available[-1] if step is None else step
    where = os.path.join(directory, str(step))
    if step not in available:
        raise CheckpointError(f"checkpoint {where}: no such step (steps: {available})")
    ocp = _ocp()
    try:
        with _manager(directory, create=False) as manager:
            header = manager.restore(step, args=ocp.args.Composite(meta=ocp.args.JsonRestore()))
        header = header.meta
        if not isinstance(header, dict) or header.get("format") != FORMAT:
            raise CheckpointError(f"checkpoint {where}: not a sac-jax checkpoint")
        meta, records = dict(header["meta"]), header["leaves"]
    except CheckpointError:
        raise
    except Exception as error:  # orbax and tensorstore raise several types on damaged input
        raise CheckpointError(f"checkpoint {where}: unreadable ({type(error).__name__})") from None
    expected, treedef = expected_leaves(template, meta, len(records), where)
    wanted = [jax.eval_shape(jax.random.key_data, x) if _is_key(x) else x for x in expected]
    for i, (record, want) in enumerate(zip(records, wanted)):
        if (tuple(record["shape"]), record["dtype"]) != (tuple(want.shape), want.dtype.name):
            raise CheckpointError(
                f"checkpoint {where}: array {i} is {record['dtype']}{record['shape']}, expected "
                f"{want.dtype.name}{list(want.shape)} (another configuration?)")
    _check_sizes(where)
    try:
        layout = _layout(records)
        with _manager(directory, create=False) as manager:
            arrays = manager.restore(step, args=ocp.args.Composite(
                state=ocp.args.StandardRestore(layout))).state if layout else {}
        stored = _unpack(arrays, records)
    except Exception as error:
        raise CheckpointError(f"checkpoint {where}: unreadable ({type(error).__name__})") from None
    leaves = []
    for i, (record, want, template_leaf, got) in enumerate(zip(records, wanted, expected, stored)):
        if (got.shape != tuple(want.shape) or got.dtype != want.dtype
                or _crc32(got) != record["crc32"]):
            raise CheckpointError(f"checkpoint {where}: damaged (array {i} does not match its "
                                  "checksum)")
        if _is_key(template_leaf):
            got = jax.random.wrap_key_data(got)
            if got.dtype != template_leaf.dtype:
                raise CheckpointError(f"checkpoint {where}: key {i} is {got.dtype}, expected "
                                      f"{template_leaf.dtype}")
        leaves.append(got)
    return jax.tree_util.tree_unflatten(treedef, leaves), meta, step
