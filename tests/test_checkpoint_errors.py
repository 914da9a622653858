"""Every refusal of `sac_jax.checkpoint.load` and `sac_jax.legacy_checkpoint.load`, on small
pytrees written here: each is one `CheckpointError` naming the checkpoint and the problem, and a
checkpoint that passes every check loads back as it was written."""

import json
import os
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import serialization

from sac_jax import checkpoint, legacy_checkpoint
from sac_jax.checkpoint import CheckpointError

TREE = {"w": np.arange(6, dtype=np.float32).reshape(2, 3), "n": np.int32(7),
        "key": jax.random.key(3)}


def written(tmp_path) -> str:
    """A checkpoint directory holding TREE as step 5."""
    directory = str(tmp_path / "checkpoints")
    checkpoint.save(directory, 5, TREE, {"note": "test"})
    return directory


def header_path(directory: str) -> str:
    return os.path.join(directory, "5", "meta", "metadata")


def rewrite_header(directory: str, change) -> None:
    """Applies `change` to the step's JSON header (the sac-jax metadata beside its arrays)."""
    with open(header_path(directory)) as f:
        header = json.load(f)
    change(header)
    with open(header_path(directory), "w") as f:
        json.dump(header, f)


def test_an_intact_checkpoint_loads_as_written(tmp_path):
    tree, meta, step = checkpoint.load(written(tmp_path), TREE)
    assert (step, meta) == (5, {"note": "test"})
    np.testing.assert_array_equal(tree["w"], TREE["w"])
    assert tree["n"] == 7
    assert jnp.array_equal(jax.random.key_data(tree["key"]), jax.random.key_data(TREE["key"]))


def test_no_checkpoint_is_not_found(tmp_path):
    with pytest.raises(CheckpointError, match=r"checkpoint .*nothing: not found$"):
        checkpoint.load(str(tmp_path / "nothing"), TREE)


def test_another_format_is_not_a_sac_jax_checkpoint(tmp_path):
    directory = written(tmp_path)
    rewrite_header(directory, lambda header: header.update(format=99))
    with pytest.raises(CheckpointError, match=r"checkpoint .*/5: not a sac-jax checkpoint$"):
        checkpoint.load(directory, TREE)


def test_an_unparsable_header_is_unreadable(tmp_path):
    directory = written(tmp_path)
    with open(header_path(directory), "w") as f:
        f.write("{not json")
    with pytest.raises(CheckpointError, match=r"checkpoint .*/5: unreadable \(\w+\)$"):
        checkpoint.load(directory, TREE)


def test_another_number_of_arrays_is_another_configuration(tmp_path):
    with pytest.raises(CheckpointError,
                       match=r"checkpoint .*/5: holds 3 arrays, this configuration has 2$"):
        checkpoint.load(written(tmp_path), {"w": TREE["w"], "n": TREE["n"]})


def test_another_shape_is_refused_before_any_data_is_read(tmp_path):
    template = dict(TREE, w=jax.ShapeDtypeStruct((3, 2), jnp.float32))
    with pytest.raises(CheckpointError, match=r"array \d is float32\[2, 3\], expected "
                                              r"float32\[3, 2\] \(another configuration\?\)$"):
        checkpoint.load(written(tmp_path), template)


def test_a_template_that_cannot_read_the_metadata(tmp_path):
    with pytest.raises(CheckpointError,
                       match=r"checkpoint .*/5: unexpected metadata \(KeyError\('size'\)\)$"):
        checkpoint.load(written(tmp_path), lambda meta: meta["size"])


def test_an_array_that_differs_from_its_checksum_is_damaged(tmp_path):
    directory = written(tmp_path)

    def change(header):
        header["leaves"][0]["crc32"] ^= 1
    rewrite_header(directory, change)
    with pytest.raises(CheckpointError,
                       match=r"checkpoint .*/5: damaged \(array 0 does not match its checksum\)$"):
        checkpoint.load(directory, TREE)


# Checkpoints of earlier sac-jax: one msgpack file.

def legacy_file(tmp_path, payload) -> str:
    path = str(tmp_path / legacy_checkpoint.FILE)
    with open(path, "wb") as f:
        f.write(payload if isinstance(payload, bytes) else serialization.msgpack_serialize(payload))
    return path


def legacy_payload(leaves, fmt=3, crc=True) -> dict:
    payload = {"format": fmt, "meta": {"note": "old"},
               "leaves": {str(i): x for i, x in enumerate(leaves)}}
    if crc:
        payload["crc32"] = {str(i): checkpoint._crc32(x) for i, x in enumerate(leaves)}
    return payload


LEGACY = {"key": jax.random.key(1), "w": np.ones(3, np.float32)}
LEGACY_LEAVES = [np.asarray(jax.random.key_data(jax.random.key(1))), np.ones(3, np.float32)]
"""LEGACY's leaves in `jax.tree_util` order, as earlier sac-jax stored them."""


@pytest.mark.parametrize("fmt", legacy_checkpoint.FORMATS)
def test_a_legacy_file_loads_with_its_format(tmp_path, fmt):
    tree, meta = legacy_checkpoint.load(
        legacy_file(tmp_path, legacy_payload(LEGACY_LEAVES, fmt, crc=fmt == 3)), LEGACY)
    assert meta == {"note": "old", "format": fmt}
    np.testing.assert_array_equal(tree["w"], LEGACY["w"])
    assert jnp.array_equal(jax.random.key_data(tree["key"]), LEGACY_LEAVES[0])


def test_legacy_missing_file(tmp_path):
    with pytest.raises(CheckpointError, match=r"checkpoint .*none.msgpack: not found$"):
        legacy_checkpoint.load(str(tmp_path / "none.msgpack"), LEGACY)


@pytest.mark.parametrize("payload, shown", [({"format": 7, "leaves": {}}, "7"),
                                            ([1, 2], "?")])
def test_legacy_other_formats(tmp_path, payload, shown):
    with pytest.raises(CheckpointError,
                       match=re.escape(f": not a sac-jax checkpoint (format {shown})") + "$"):
        legacy_checkpoint.load(legacy_file(tmp_path, payload), LEGACY)


def test_legacy_garbage_is_unreadable(tmp_path):
    with pytest.raises(CheckpointError, match=r": unreadable \(\w+\)$"):
        legacy_checkpoint.load(legacy_file(tmp_path, b"\xc1\x00 not msgpack"), LEGACY)


def test_legacy_checksum_mismatch_is_damaged(tmp_path):
    payload = legacy_payload(LEGACY_LEAVES)
    payload["leaves"]["1"] = np.full(3, 2, np.float32)  # not the bytes its CRC was taken of
    with pytest.raises(CheckpointError, match=r": damaged \(array 1 does not match its "
                                              r"checksum\)$"):
        legacy_checkpoint.load(legacy_file(tmp_path, payload), LEGACY)


def test_legacy_key_of_another_shape(tmp_path):
    payload = legacy_payload([np.zeros(3, np.uint32), LEGACY_LEAVES[1]])
    with pytest.raises(CheckpointError, match=r": key 0 has shape \(3,\), expected \(2,\)$"):
        legacy_checkpoint.load(legacy_file(tmp_path, payload), LEGACY)


def test_legacy_array_of_another_dtype(tmp_path):
    payload = legacy_payload([LEGACY_LEAVES[0], np.ones(3, np.float64)])
    with pytest.raises(CheckpointError, match=r": array 1 is float64\[3\], expected "
                                              r"float32\[3\] \(another configuration\?\)$"):
        legacy_checkpoint.load(legacy_file(tmp_path, payload), LEGACY)
