"""Files written whole or not at all: under a temporary name in the same directory, then
renamed (a rename within one filesystem is atomic). Every file sac-jax writes outside orbax's
checkpoint arrays and TensorBoard's event file (appended to point by point, and rebuilt whole
on a resume: `sac_jax.metric_writers.rebuild`) goes through `write_file`."""

from __future__ import annotations

import json
import os


def write_file(path: str, data: bytes, replace: bool = True) -> None:
    """Writes `data` to `path` under a temporary name in the same directory, then renames it:
    whole or absent. Without `replace` an existing `path` is kept (FileExistsError, even if it
    appeared during the write). On an OSError (a missing or unwritable directory, a full disk)
    no temporary file is left."""
    tmp = f"{path}.tmp-{os.getpid()}"
    try:
        with open(tmp, "wb") as f:
            f.write(data)
        if replace:
            os.replace(tmp, path)
        else:
            os.link(tmp, path)  # fails if `path` exists: never overwrites
    finally:
        if os.path.lexists(tmp):
            os.remove(tmp)


def write_json(path: str, obj) -> None:
    """`obj` as indented JSON text, through `write_file`."""
    write_file(path, (json.dumps(obj, indent=2) + "\n").encode())
