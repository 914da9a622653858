"""Checkpoints of earlier sac-jax (formats 2 and 3): the whole training state in one msgpack
file, `checkpoint.msgpack` in the run directory, read so that the policies they hold stay
loadable. sac-jax now writes orbax checkpoints (`sac_jax.checkpoint`).

File layout (flax's msgpack encoding, never pickle):
    {"format": 2 or 3, "meta": {...JSON-able...}, "leaves": {"0": array, "1": array, ...},
     "crc32": {"0": int, "1": int, ...}}
Leaves are the `jax.tree_util` leaves of the saved pytree in order, PRNG keys as their key
data; "crc32" (in format 3 files of the last msgpack versions) holds each leaf's CRC-32,
checked on load. Format 2 holds no delivered actor and no stop flags; `load` says which
format it read in the returned meta's "format".
"""

from __future__ import annotations

import os
from typing import Any, Callable, Tuple, Union

import jax
import numpy as np
from flax import serialization

from sac_jax.checkpoint import CheckpointError, _crc32, _is_key, expected_leaves

FILE = "checkpoint.msgpack"
FORMATS = (2, 3)


def load(path: str, template: Union[Any, Callable[[dict], Any]]) -> Tuple[Any, dict]:
    """Reads the checkpoint at `path` into the structure of `template` (a pytree of arrays or
    `jax.ShapeDtypeStruct`s, or a function of the stored `meta` returning one); returns
    (tree, meta), meta["format"] being the file's format (one of `FORMATS`). Raises
    `CheckpointError` naming the path and the problem."""
    if not os.path.isfile(path):
        raise CheckpointError(f"checkpoint {path}: not found")
    try:
        with open(path, "rb") as f:
            payload = serialization.msgpack_restore(f.read())
        if not isinstance(payload, dict) or payload.get("format") not in FORMATS:
            raise CheckpointError(f"checkpoint {path}: not a sac-jax checkpoint (format "
                                  f"{payload.get('format') if isinstance(payload, dict) else '?'})")
        stored, meta = payload["leaves"], dict(payload["meta"], format=payload["format"])
        checksums = payload.get("crc32")
    except CheckpointError:
        raise
    except Exception as error:  # msgpack raises several types on damaged input
        raise CheckpointError(f"checkpoint {path}: unreadable ({type(error).__name__})") from None
    expected, treedef = expected_leaves(template, meta, len(stored), path)
    leaves = []
    for i, want in enumerate(expected):
        got = np.asarray(stored[str(i)])
        if checksums is not None and _crc32(got) != checksums.get(str(i)):
            raise CheckpointError(f"checkpoint {path}: damaged (array {i} does not match its "
                                  "checksum)")
        if _is_key(want):
            ref = jax.eval_shape(jax.random.key_data, want)
            if got.shape != ref.shape or got.dtype != ref.dtype:
                raise CheckpointError(f"checkpoint {path}: key {i} has shape {got.shape}, "
                                      f"expected {ref.shape}")
            key = jax.random.wrap_key_data(got)
            if key.dtype != want.dtype:
                raise CheckpointError(f"checkpoint {path}: key {i} is {key.dtype}, expected "
                                      f"{want.dtype}")
            leaves.append(key)
            continue
        if got.shape != tuple(want.shape) or got.dtype != want.dtype:
            raise CheckpointError(f"checkpoint {path}: array {i} is {got.dtype}"
                                  f"{list(got.shape)}, expected {want.dtype}"
                                  f"{list(want.shape)} (another configuration?)")
        leaves.append(got)
    return jax.tree_util.tree_unflatten(treedef, leaves), meta
