"""Checkpoints: a whole training state (every pytree leaf, PRNG keys included) in one msgpack
file, written under a temporary name and renamed, and read back against a template.

File layout (flax's msgpack encoding, never pickle):
    {"format": FORMAT, "meta": {...JSON-able...}, "leaves": {"0": array, "1": array, ...},
     "crc32": {"0": int, "1": int, ...}}
"crc32" holds each leaf's CRC-32 of its bytes (`zlib.crc32`), checked on load: bytes flipped
inside an array's data, which msgpack would read back as other numbers, are refused with
`CheckpointError` naming the file and the array. (Files of earlier sac-jax carry no checksums
and load unchecked.)
Leaves are the `jax.tree_util` leaves of the saved pytree in order; typed PRNG key arrays (of JAX's default
implementation) are stored as their raw `jax.random.key_data` and re-wrapped on load. Loading checks every leaf's
shape and dtype against the template (`jax.eval_shape` of the state's constructor), so a
checkpoint from another configuration, or a damaged file, is refused with `CheckpointError`
before anything is built from it.
"""

from __future__ import annotations

import os
import zlib
from typing import Any, Callable, Tuple, Union

import jax
import numpy as np
from flax import serialization

FORMAT = 3
"""Format 3 holds the delivered actor and the stop flags (`sac_jax.selection`); format 2, of
earlier sac-jax, holds the same state without them. `load` reads both and says which in the
returned meta's "format"."""
FORMATS = (2, FORMAT)


class CheckpointError(ValueError):
    """A checkpoint that is missing, unreadable, or does not fit the expected state."""


def _is_key(leaf) -> bool:
    return jax.dtypes.issubdtype(leaf.dtype, jax.dtypes.prng_key)


def _stored_leaves(tree: Any) -> list:
    """The leaves of `tree` as `save` stores them, on the host: PRNG keys as their key data."""
    return jax.device_get([jax.random.key_data(x) if _is_key(x) else x
                           for x in jax.tree_util.tree_leaves(tree)])


def to_host(tree: Any) -> list:
    """`_stored_leaves` as numpy arrays of their own (copies: on a CPU a fetched array may share
    memory with a device buffer that a later donation reuses). `save(path, to_host(tree), meta)`
    writes the same file as `save(path, tree, meta)`."""
    return [np.array(x) for x in _stored_leaves(tree)]


def _crc32(array: np.ndarray) -> int:
    return zlib.crc32(np.ascontiguousarray(array).view(np.uint8).reshape(-1))


def save(path: str, tree: Any, meta: dict) -> None:
    """Writes `tree` and `meta` to `path` atomically (temporary file in the same directory, then
    `os.replace`): however the process is stopped, `path` holds either the previous checkpoint or
    this one. (No fsync: this guards against stopped processes, not against power loss.)"""
    leaves = {str(i): np.asarray(x) for i, x in enumerate(_stored_leaves(tree))}
    payload = {"format": FORMAT, "meta": meta, "leaves": leaves,
               "crc32": {i: _crc32(x) for i, x in leaves.items()}}
    tmp = f"{path}.tmp-{os.getpid()}"
    try:
        with open(tmp, "wb") as f:
            f.write(serialization.msgpack_serialize(payload))
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


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
    if callable(template):
        try:
            template = template(meta)
        except CheckpointError:
            raise
        except (KeyError, TypeError, ValueError) as error:
            raise CheckpointError(f"checkpoint {path}: unexpected metadata ({error!r})") from None
    expected, treedef = jax.tree_util.tree_flatten(template)
    if len(stored) != len(expected):
        raise CheckpointError(f"checkpoint {path}: holds {len(stored)} arrays, this "
                              f"configuration has {len(expected)}")
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
            raise CheckpointError(f"checkpoint {path}: array {i} is {got.dtype}{list(got.shape)}, "
                                  f"expected {want.dtype}{list(want.shape)} (another configuration?)")
        leaves.append(got)
    return jax.tree_util.tree_unflatten(treedef, leaves), meta
