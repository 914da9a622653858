"""sac_jax.run_checkpoint and sac_jax.checkpoint: the whole state comes back bit for bit, only
the filled replay slots are stored, saving at a new fill level compiles nothing, the background
writer stores the state as it was when asked without holding up the caller, writing the newest
of the states waiting; a checkpoint whose metadata does not fit is refused. (Damaged
checkpoints, full disks and half-written steps: tests/test_faults.py.)"""

import json
import re
import logging
import os
import threading

import jax
import numpy as np
import pytest

from sac_jax import checkpoint, memory, run_checkpoint
from sac_jax.position import Position
from tests.saved_runs import (checkpoint_header, copied_run, newest_checkpoint,
                              two_checkpoints)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    return two_checkpoints(str(tmp_path_factory.mktemp("ckpt") / "run"))


def _leaves(tree):
    return [np.asarray(jax.random.key_data(x)) if jax.dtypes.issubdtype(x.dtype, jax.dtypes.prng_key)
            else np.asarray(x) for x in jax.tree_util.tree_leaves(tree)]


def _assert_same(a, b):
    for x, y in zip(_leaves(a), _leaves(b), strict=True):
        assert x.dtype == y.dtype and x.shape == y.shape
        np.testing.assert_array_equal(x, y)


def test_the_state_comes_back_bit_for_bit(run):
    out, saved = run
    _, info, loaded, position = run_checkpoint.load_checkpoint(out)
    assert (position.chunks_done, position.env_steps, info.seeds) == (3, 800, 2)
    _assert_same(saved, loaded)
    assert run_checkpoint.saved_steps(out) == [0, 800]
    _, _, first, _ = run_checkpoint.load_checkpoint(out, step=0)  # the earlier step, on request
    assert int(first.buffer.size) == 0


def test_a_run_resumed_from_an_earlier_step_saves_in_place_of_the_later_ones(run, tmp_path):
    """Resumed from step 0 of a run that also holds step 800, the next save (400) replaces 800:
    orbax writes only steps after its newest, and the save had failed."""
    copy = copied_run(run[0], tmp_path)
    _, _, first, _ = run_checkpoint.load_checkpoint(copy, step=0)
    run_checkpoint.save_checkpoint(copy, first, Position(chunks_done=1, env_steps=400))
    assert run_checkpoint.saved_steps(copy) == [0, 400]
    _assert_same(first, run_checkpoint.load_checkpoint(copy)[2])


def test_only_the_filled_replay_slots_are_stored(run):
    out, saved = run
    header = checkpoint_header(newest_checkpoint(out))
    assert header["meta"]["buffer_filled"] == 40
    assert np.asarray(saved.buffer.data.obs).shape == (2, 4000, 3)
    shapes = [tuple(record["shape"]) for record in header["leaves"]]
    assert (2, 40, 3) in shapes and (2, 4000, 3) not in shapes


@pytest.mark.parametrize("device_copy", [False, True], ids=["in line", "device copy"])
def test_saving_at_new_fill_levels_compiles_nothing(run, tmp_path, caplog, monkeypatch,
                                                    device_copy):
    """A run saves after every chunk, each time with more slots filled. Cut on the device, each
    new length compiled a slice program: 0.13 s of host time per chunk of the `fast` preset on
    the CPU, while the device waited (BENCHMARKS.md). Fetched in line (a CPU's path), nothing is
    cut on the device; the writer's device copy (an accelerator's path, forced here) cuts to a
    power of two of slots, so 41 and 42 filled slots reuse the slice of 64 that 40 compiled."""
    copies = []
    if device_copy:
        monkeypatch.setattr(run_checkpoint, "_on_host", lambda tree: False)
        monkeypatch.setattr(run_checkpoint, "_room_for_copy", lambda tree: True)
        monkeypatch.setattr(memory, "IN_LINE_COPY_BYTES", 0)
        copy = run_checkpoint._device_copy
        monkeypatch.setattr(run_checkpoint, "_device_copy",
                            lambda tree: copies.append(_filled_slots(tree)) or copy(tree))
    _, saved = run
    runner = jax.device_put(saved)  # device arrays, as a run's state
    writer = run_checkpoint.CheckpointWriter(str(tmp_path / "writer"), min_interval_s=0)
    at = lambda filled: runner.replace(buffer=runner.buffer.replace(
        size=jax.device_put(np.int32(filled))))
    writer.save(at(40), Position(chunks_done=1, env_steps=40))  # the first save's programs
    with jax.log_compiles(True), caplog.at_level(logging.WARNING):
        for filled in (41, 42):
            position = Position(chunks_done=1, env_steps=filled)
            run_checkpoint.save_checkpoint(str(tmp_path), at(filled), position)
            writer.save(at(filled), position)
        writer.close()
    assert not [r.getMessage() for r in caplog.records if "ompil" in r.getMessage()]
    assert copies == ([40, 41, 42] if device_copy else [])


def _filled_slots(runner) -> int:
    return int(np.max(np.asarray(runner.buffer.size)))


def _stored_arrays(out, step):
    """The arrays of checkpoint `step` of `out`, read back without a template."""
    header = checkpoint_header(os.path.join(run_checkpoint.directory(out), str(step)))
    template = [jax.ShapeDtypeStruct(r["shape"], np.dtype(r["dtype"])) for r in header["leaves"]]
    tree, meta, _ = checkpoint.load(run_checkpoint.directory(out), template, step)
    return tree, meta


def _same_checkpoint(a, b, step):
    (tree_a, meta_a), (tree_b, meta_b) = _stored_arrays(a, step), _stored_arrays(b, step)
    assert meta_a == meta_b
    _assert_same(tree_a, tree_b)


@pytest.mark.parametrize("room, small", [(True, False), (False, False), (True, True)],
                         ids=["device copy", "no room: fetched in line", "small: fetched in line"])
def test_background_writer_stores_the_state_as_it_was_asked(run, tmp_path, monkeypatch, room,
                                                            small):
    """The device buffers are deleted (as the next chunk's donation does) and the position
    changed right after `save`: the checkpoint still holds the state and position of the call,
    array for array what `save_checkpoint` writes, whether the device had room for a copy of
    the state or not, or the copy was small enough to fetch in line (the paths of an
    accelerator, forced here); a device copy is made on the first path only."""
    monkeypatch.setattr(run_checkpoint, "_on_host", lambda tree: False)
    monkeypatch.setattr(run_checkpoint, "_room_for_copy", lambda tree: room)
    monkeypatch.setattr(memory, "IN_LINE_COPY_BYTES", 1 << 40 if small else 0)
    copies = []
    device_copy = run_checkpoint._device_copy
    monkeypatch.setattr(run_checkpoint, "_device_copy",
                        lambda tree: copies.append(1) or device_copy(tree))
    _, saved = run
    run_checkpoint.save_checkpoint(str(tmp_path / "direct"), saved, Position(chunks_done=3, env_steps=9))
    runner = jax.tree_util.tree_map(lambda x: jax.device_put(x).copy(), saved)  # its own buffers
    position = Position(chunks_done=3, env_steps=9)
    writer = run_checkpoint.CheckpointWriter(str(tmp_path / "writer"), min_interval_s=0)
    writer.save(runner, position)
    for leaf in jax.tree_util.tree_leaves(runner):
        leaf.delete()
    position.chunks_done = 4
    writer.close()
    _same_checkpoint(str(tmp_path / "writer"), str(tmp_path / "direct"), 9)
    assert len(copies) == (room and not small)


def test_a_device_copy_holds_the_filled_slots_rounded_up_to_a_power_of_two(run):
    """40 of 4000 slots filled: the copy holds 64 (`memory.stored_slots`), the 40 filled ones
    as they are; every other array whole."""
    _, saved = run
    copy = run_checkpoint._device_copy(saved)
    for kept, whole in zip(jax.tree_util.tree_leaves(copy.buffer.data),
                           jax.tree_util.tree_leaves(saved.buffer.data), strict=True):
        assert kept.shape == whole.shape[:1] + (64,) + whole.shape[2:]
        np.testing.assert_array_equal(np.asarray(kept)[:, :40], np.asarray(whole)[:, :40])
    _assert_same(copy.replace(buffer=copy.buffer.replace(data=None)),
                 saved.replace(buffer=saved.buffer.replace(data=None)))
    assert [memory.stored_slots(n, 4000, "gpu") for n in (0, 1, 40, 64, 65, 3000, 4000)] == [
        0, 1, 64, 64, 128, 4000, 4000]
    assert memory.stored_slots(40, 4000, "cpu") == 40


def test_background_writer_returns_at_once_and_writes_the_newest_state_waiting(
        run, tmp_path, monkeypatch):
    """On an accelerator (device copies; forced here): while the first write is held up, three
    more saves return and queue; once it is let go, only the newest of them is written, and its
    state is the one that was saved."""
    monkeypatch.setattr(run_checkpoint, "_on_host", lambda tree: False)
    monkeypatch.setattr(memory, "IN_LINE_COPY_BYTES", 0)
    written, started, release = [], threading.Event(), threading.Event()

    def slow_save(directory, runner, position):
        if not written:
            started.set()
            assert release.wait(timeout=60)
        written.append((position.chunks_done, int(runner.buffer.size)))

    monkeypatch.setattr(run_checkpoint, "save_checkpoint", slow_save)
    writer = run_checkpoint.CheckpointWriter(str(tmp_path), min_interval_s=0)
    _, saved = run
    save = lambda n: writer.save(saved.replace(buffer=saved.buffer.replace(size=np.int32(n))),
                                 Position(chunks_done=n, env_steps=n))
    save(1)
    assert started.wait(timeout=60)
    for n in (2, 3, 4):
        save(n)
    release.set()
    writer.close()
    assert written == [(1, 1), (4, 4)]


def test_states_are_saved_at_most_every_min_interval_and_where_the_run_ends(
        run, tmp_path, monkeypatch):
    """Saves within the interval are skipped; the one where the run ends is written."""
    written = []
    monkeypatch.setattr(run_checkpoint, "_write", lambda directory, leaves, filled, position: (
        written.append(position.env_steps)))
    writer = run_checkpoint.CheckpointWriter(str(tmp_path), min_interval_s=3600)
    for n in (1, 2, 3):
        writer.save(run[1], Position(chunks_done=n, env_steps=n, ends_run=n == 3))
    writer.close()
    assert written == [3]
    writer = run_checkpoint.CheckpointWriter(str(tmp_path), min_interval_s=0)
    for n in (4, 5):
        writer.save(run[1], Position(chunks_done=n, env_steps=n, ends_run=False))
    writer.close()
    assert written == [3, 4, 5]


def test_on_the_cpu_a_save_copies_the_filled_replay_slots_only(run, tmp_path, monkeypatch):
    """A state in host memory is fetched in line (a view) and the copy the write keeps holds
    the 40 filled slots of the 4000, not a copy of every slot; the checkpoint is the one
    `save_checkpoint` writes."""
    kept = []
    write = run_checkpoint._write
    monkeypatch.setattr(run_checkpoint, "_write", lambda directory, leaves, filled, position: (
        kept.append((filled, leaves)), write(directory, leaves, filled, position)))
    _, saved = run
    writer = run_checkpoint.CheckpointWriter(str(tmp_path / "writer"), min_interval_s=0)
    writer.save(saved, Position(chunks_done=3, env_steps=5))
    writer.close()
    (filled, leaves), = kept
    assert filled == 40  # replay leaves (seeds, slots, ...): 40 slots kept, none of 4000
    assert any(leaf.ndim > 1 and leaf.shape[1] == 40 for leaf in leaves)
    assert not any(leaf.ndim > 1 and leaf.shape[1] == 4000 for leaf in leaves)
    run_checkpoint.save_checkpoint(str(tmp_path / "direct"), saved, Position(chunks_done=3, env_steps=5))
    _same_checkpoint(str(tmp_path / "writer"), str(tmp_path / "direct"), 5)


def test_on_the_cpu_without_room_for_the_copy_a_save_writes_the_state_itself_in_line(
        run, tmp_path, monkeypatch):
    """Host memory with no room for the copy (`memory.copy_fits`): `save` writes before it
    returns, from the state's own memory (the replay leaves it writes share it), and the
    checkpoint is the one `save_checkpoint` writes."""
    kept = []
    write = run_checkpoint._write
    monkeypatch.setattr(run_checkpoint, "_write", lambda directory, leaves, filled, position: (
        kept.append(leaves), write(directory, leaves, filled, position)))
    monkeypatch.setattr(memory, "available", lambda device=None: (1000, "cpu"))
    _, saved = run
    writer = run_checkpoint.CheckpointWriter(str(tmp_path / "writer"), min_interval_s=0)
    writer.save(saved, Position(chunks_done=3, env_steps=5))
    assert len(kept) == 1 and run_checkpoint.saved_steps(str(tmp_path / "writer")) == [5]
    writer.close()
    obs = np.asarray(saved.buffer.data.obs)
    assert any(np.shares_memory(leaf, obs) for leaf in kept[0])
    run_checkpoint.save_checkpoint(str(tmp_path / "direct"), saved, Position(chunks_done=3, env_steps=5))
    _same_checkpoint(str(tmp_path / "writer"), str(tmp_path / "direct"), 5)


@pytest.mark.parametrize("filled", [4001, -1, "40", None])
def test_a_fill_level_that_does_not_fit_is_refused(run, tmp_path, filled):
    copy = copied_run(run[0], tmp_path)
    path = os.path.join(newest_checkpoint(copy), "meta", "metadata")
    header = checkpoint_header(newest_checkpoint(copy))
    header["meta"]["buffer_filled"] = filled
    with open(path, "w") as f:
        json.dump(header, f)
    with pytest.raises(checkpoint.CheckpointError,
                       match="unexpected metadata .*" + re.escape(
                           f"buffer_filled={filled!r} outside [0, 4000]")):
        run_checkpoint.load_checkpoint(copy)


def test_a_checkpoint_of_another_configuration_is_refused(run, tmp_path):
    copy = copied_run(run[0], tmp_path)
    with open(os.path.join(copy, "config.json")) as f:
        config = json.load(f)
    with open(os.path.join(copy, "config.json"), "w") as f:
        json.dump(dict(config, critic_hidden=[h + 1 for h in config["critic_hidden"]]), f)
    with pytest.raises(checkpoint.CheckpointError, match=r"array \d+ is float32\[.*expected "
                                                         r"float32\[.*another configuration"):
        run_checkpoint.load_checkpoint(copy)


