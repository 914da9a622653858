"""What a W&B run holds locally: the history steps logged in its transaction logs (the
`run-<id>.wandb` file W&B writes in each of the run's directories), read back without the
network.

A resumed offline run starts a new local directory and W&B does not know what the earlier
ones hold, so `sac_jax.tracking` reads them here to log each point once. wandb 0.31 ships no
Python reader of these files (the earlier `wandb.sdk.internal.datastore` was removed), so
this module reads their framing, LevelDB's log format: a 7-byte file header (":W&B", a
2-byte magic, a version byte), then 32 KiB blocks of chunks, each a 7-byte header (CRC-32 of
the type byte and the data, little-endian length, type: whole, first, middle, last) and data;
a block's tail too short for a header is padding. Each record is a `wandb_internal_pb2.Record`
protobuf, parsed with wandb's own message class. A chunk cut short or failing its CRC (a
process killed while writing) ends the log there.
"""

from __future__ import annotations

import glob
import json
import os
import struct
import zlib
from typing import Dict, Iterator, List

_FILE_HEADER = struct.Struct("<4sHB")
_CHUNK_HEADER = struct.Struct("<IHB")
_BLOCK = 32768
_WHOLE, _FIRST, _MIDDLE, _LAST = 1, 2, 3, 4


class UnreadableLog(ValueError):
    """A file that is not a W&B transaction log."""


def records(path: str) -> Iterator[bytes]:
    """The serialized records of the transaction log at `path`, in order, up to the first
    chunk that is cut short or damaged (none for a log cut short within its file header)."""
    with open(path, "rb") as f:
        data = f.read()
    if len(data) < _FILE_HEADER.size and b":W&B".startswith(data[:4]):
        return
    if len(data) < _FILE_HEADER.size or _FILE_HEADER.unpack_from(data)[0] != b":W&B":
        raise UnreadableLog(f"{path}: not a W&B transaction log")
    at, pending = _FILE_HEADER.size, b""
    while at + _CHUNK_HEADER.size <= len(data):
        room = _BLOCK - at % _BLOCK
        if room < _CHUNK_HEADER.size:  # padding at the end of a block
            at += room
            continue
        crc, length, kind = _CHUNK_HEADER.unpack_from(data, at)
        chunk = data[at + _CHUNK_HEADER.size:at + _CHUNK_HEADER.size + length]
        if len(chunk) < length or zlib.crc32(chunk, zlib.crc32(bytes([kind]))) != crc:
            return
        at += _CHUNK_HEADER.size + length
        if kind == _WHOLE:
            yield chunk
        elif kind == _FIRST:
            pending = chunk
        elif kind == _MIDDLE:
            pending += chunk
        elif kind == _LAST:
            yield pending + chunk
            pending = b""
        else:
            return


def history(path: str) -> List[Dict[str, object]]:
    """Each history row logged in the transaction log at `path`: {key: value}, `_step`
    included."""
    from wandb.proto import wandb_internal_pb2

    rows = []
    for data in records(path):
        record = wandb_internal_pb2.Record.FromString(data)
        if record.WhichOneof("record_type") == "history":
            rows.append({item.key or "/".join(item.nested_key): json.loads(item.value_json)
                         for item in record.history.item})
    return rows


def summary(path: str) -> Dict[str, object]:
    """The run summary as the transaction log at `path` leaves it: its summary updates in
    order, the later winning."""
    from wandb.proto import wandb_internal_pb2

    values: Dict[str, object] = {}
    for data in records(path):
        record = wandb_internal_pb2.Record.FromString(data)
        if record.WhichOneof("record_type") == "summary":
            for item in record.summary.update:
                values[item.key or "/".join(item.nested_key)] = json.loads(item.value_json)
            for item in record.summary.remove:
                values.pop(item.key or "/".join(item.nested_key), None)
    return values


def logs(wandb_dir: str, run_id: str) -> List[str]:
    """The transaction logs of run `run_id` under `wandb_dir` (the `dir` given to
    `wandb.init`: W&B writes `wandb/<mode>-run-<time>-<id>/run-<id>.wandb` there, and
    `<mode>-run-<time>-<id>-1/` for a second process of the run started in the same second),
    oldest first."""
    pattern = os.path.join(glob.escape(wandb_dir), "wandb", f"*run-*-{glob.escape(run_id)}*",
                           f"run-{glob.escape(run_id)}.wandb")
    def started(path):  # the directory's name after "run-": the time the process started
        name = os.path.basename(os.path.dirname(path))
        return name[name.index("run-") + 4:]

    return sorted(glob.glob(pattern), key=started)


def steps(path: str) -> List[int]:
    """The history steps logged in the transaction log at `path`."""
    return [int(row["_step"]) for row in history(path) if "_step" in row]
