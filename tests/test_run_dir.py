"""sac_jax.run_dir checkpoints: the whole state comes back bit for bit, only the filled replay
slots are stored, saving at a new fill level compiles nothing, the background writer stores
the state as it was when asked without holding up the caller, writing the newest of the states
waiting, and a checkpoint whose metadata does not fit is refused; the TensorBoard writer
imports no torch."""

import logging
import os
import threading

import jax
import numpy as np
import pytest
from flax import serialization

from sac_jax import checkpoint, run_dir
from tests.saved_runs import untrained
from tests.subprocess_json import run_json


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A Pendulum-v1 run directory of 2 seeds whose state has 40 of 4000 replay slots filled."""
    out = untrained(str(tmp_path_factory.mktemp("ckpt") / "run"), "Pendulum-v1", seeds=2,
                    buffer_size=4000, total_steps=6000, learning_starts=2000, eval_every=2000,
                    num_envs=8)
    _, _, runner, position = run_dir.load_checkpoint(out)
    rng = np.random.default_rng(0)
    data = jax.tree_util.tree_map(lambda x: np.concatenate(
        [rng.normal(size=(x.shape[0], 40) + x.shape[2:]).astype(x.dtype), x[:, 40:]], axis=1),
        runner.buffer.data)
    runner = runner.replace(buffer=runner.buffer.replace(data=data, size=np.int32(40)))
    run_dir.save_checkpoint(out, runner, dict(position, chunks_done=3))
    return out, runner


def _leaves(tree):
    return [np.asarray(jax.random.key_data(x)) if jax.dtypes.issubdtype(x.dtype, jax.dtypes.prng_key)
            else np.asarray(x) for x in jax.tree_util.tree_leaves(tree)]


def test_the_state_comes_back_bit_for_bit(run):
    out, saved = run
    _, _, loaded, position = run_dir.load_checkpoint(out)
    assert position["chunks_done"] == 3
    for a, b in zip(_leaves(saved), _leaves(loaded), strict=True):
        assert a.dtype == b.dtype and a.shape == b.shape
        np.testing.assert_array_equal(a, b)


def test_only_the_filled_replay_slots_are_stored(run):
    out, saved = run
    with open(os.path.join(out, run_dir.CHECKPOINT), "rb") as f:
        payload = serialization.msgpack_restore(f.read())
    assert payload["meta"]["buffer_filled"] == 40
    obs = np.asarray(saved.buffer.data.obs)
    assert obs.shape == (2, 4000, 3)
    shapes = [np.asarray(x).shape for x in payload["leaves"].values()]
    assert (2, 40, 3) in shapes and (2, 4000, 3) not in shapes


def test_saving_at_new_fill_levels_compiles_nothing(run, tmp_path, caplog):
    """A run saves after every chunk, each time with more slots filled. Cut on the device, each
    new length compiled a slice program: 0.13 s of host time per chunk of the `fast` preset on
    the CPU, while the device waited (BENCHMARKS.md)."""
    _, saved = run
    runner = jax.device_put(saved)  # device arrays, as a run's state
    writer = run_dir.CheckpointWriter(str(tmp_path / "writer"))
    (tmp_path / "writer").mkdir()
    with jax.log_compiles(True), caplog.at_level(logging.WARNING):
        for filled in (41, 42):
            state = runner.replace(buffer=runner.buffer.replace(
                size=jax.device_put(np.int32(filled))))
            run_dir.save_checkpoint(str(tmp_path), state, {"chunks_done": 1})
            writer.save(state, {"chunks_done": 1})  # nor does the writer's device-side copy
        writer.close()
    assert not [r.getMessage() for r in caplog.records if "ompil" in r.getMessage()]


@pytest.mark.parametrize("room", [True, False], ids=["device copy", "no room: fetched in line"])
def test_background_writer_stores_the_state_as_it_was_asked(run, tmp_path, monkeypatch, room):
    """The device buffers are deleted (as the next chunk's donation does) and the position
    changed right after `save`: the file still holds the state and position of the call,
    byte for byte what `save_checkpoint` writes, whether the device had room for a copy of the
    state or not."""
    monkeypatch.setattr(run_dir, "_room_for_copy", lambda tree: room)
    _, saved = run
    (tmp_path / "writer").mkdir(), (tmp_path / "direct").mkdir()
    run_dir.save_checkpoint(str(tmp_path / "direct"), saved, {"chunks_done": 3})
    runner = jax.tree_util.tree_map(lambda x: jax.device_put(x).copy(), saved)  # its own buffers
    position = {"chunks_done": 3}
    writer = run_dir.CheckpointWriter(str(tmp_path / "writer"))
    writer.save(runner, position)
    for leaf in jax.tree_util.tree_leaves(runner):
        leaf.delete()
    position["chunks_done"] = 4
    writer.close()
    written, direct = (tmp_path / name / run_dir.CHECKPOINT for name in ("writer", "direct"))
    assert written.read_bytes() == direct.read_bytes()


def test_background_writer_returns_at_once_and_writes_the_newest_state_waiting(
        run, tmp_path, monkeypatch):
    """On an accelerator (device copies; forced here): while the first write is held up, three
    more saves return and queue; once it is let go, only the newest of them is written, and its
    state is the one that was saved."""
    monkeypatch.setattr(run_dir, "_on_host", lambda tree: False)
    written, started, release = [], threading.Event(), threading.Event()

    def slow_save(directory, runner, position):
        if not written:
            started.set()
            assert release.wait(timeout=60)
        written.append((position["chunks_done"], int(runner.buffer.size)))

    monkeypatch.setattr(run_dir, "save_checkpoint", slow_save)
    writer = run_dir.CheckpointWriter(str(tmp_path))
    _, saved = run
    save = lambda n: writer.save(saved.replace(buffer=saved.buffer.replace(size=np.int32(n))),
                                 {"chunks_done": n})
    save(1)
    assert started.wait(timeout=60)
    for n in (2, 3, 4):
        save(n)
    release.set()
    writer.close()
    assert written == [(1, 1), (4, 4)]


def test_on_the_cpu_a_save_copies_the_filled_replay_slots_only(run, tmp_path, monkeypatch):
    """A state in host memory is fetched in line (a view) and the copy the write keeps holds
    the 40 filled slots of the 4000, not a copy of every slot; the file is the one
    `save_checkpoint` writes."""
    kept = []
    write = run_dir._write_leaves
    monkeypatch.setattr(run_dir, "_write_leaves", lambda directory, leaves, filled, position: (
        kept.append((filled, leaves)), write(directory, leaves, filled, position)))
    _, saved = run
    writer = run_dir.CheckpointWriter(str(tmp_path))
    writer.save(saved, {"chunks_done": 3})
    writer.close()
    (filled, leaves), = kept
    assert filled == 40  # replay leaves (seeds, slots, ...): 40 slots kept, none of 4000
    assert any(leaf.ndim > 1 and leaf.shape[1] == 40 for leaf in leaves)
    assert not any(leaf.ndim > 1 and leaf.shape[1] == 4000 for leaf in leaves)
    direct = tmp_path / "direct"
    os.makedirs(direct)
    run_dir.save_checkpoint(str(direct), saved, {"chunks_done": 3})
    assert (tmp_path / run_dir.CHECKPOINT).read_bytes() == (direct / run_dir.CHECKPOINT).read_bytes()


def test_background_writer_reraises_a_failed_write(run, tmp_path):
    writer = run_dir.CheckpointWriter(str(tmp_path / "missing"))
    writer.save(run[1], {"chunks_done": 3})
    with pytest.raises(FileNotFoundError, match="missing"):
        writer.close()


@pytest.mark.parametrize("filled", [4001, -1, "40", None])
def test_a_fill_level_that_does_not_fit_is_refused(run, tmp_path, filled):
    out, _ = run
    with open(os.path.join(out, run_dir.CHECKPOINT), "rb") as f:
        payload = serialization.msgpack_restore(f.read())
    payload["meta"]["buffer_filled"] = filled
    copy = tmp_path / "copy"
    os.makedirs(copy)
    for name in ("config.json", "run.json"):
        (copy / name).write_bytes(open(os.path.join(out, name), "rb").read())
    (copy / run_dir.CHECKPOINT).write_bytes(serialization.msgpack_serialize(payload))
    with pytest.raises(checkpoint.CheckpointError, match="unexpected metadata|array"):
        run_dir.load_checkpoint(str(copy))


def test_tensorboard_writer_leaves_torch_unimported(tmp_path):
    """The TensorBoard writer (with a point written) imports no torch, which tensorboardX's
    writer did where torch is installed (2.2 s on the CPU), nor TensorFlow; an `import torch`
    afterwards still works."""
    pytest.importorskip("torch")
    script = ("import json, sys; from sac_jax import metric_writers; "
              f"board = metric_writers.TensorBoard({str(tmp_path)!r}); "
              "board.add_point(1000, {'eval_return': 1.0}, [1.0]); board.close(); "
              "before = sorted({'torch', 'tensorflow'} & set(sys.modules)); import torch; "
              "print(json.dumps({'before': before, 'after': 'torch' in sys.modules}))")
    assert run_json(["-c", script]) == {"before": [], "after": True}
    from tests.killed_run import tensorboard_steps
    # it did write the point (step 0: the event that starts every event file)
    assert tensorboard_steps(str(tmp_path / "tensorboard")) == {0, 1000}


def _damaged_copy(out, tmp_path):
    """A copy of the run directory `out` with bytes flipped in the middle of its checkpoint's
    largest array (the replay observations): the file still parses."""
    copy = tmp_path / "damaged"
    os.makedirs(copy)
    for name in ("config.json", "run.json"):
        (copy / name).write_bytes(open(os.path.join(out, name), "rb").read())
    data = bytearray(open(os.path.join(out, run_dir.CHECKPOINT), "rb").read())
    with open(os.path.join(out, run_dir.CHECKPOINT), "rb") as f:
        payload = serialization.msgpack_restore(f.read())
    largest = max(payload["leaves"].values(), key=lambda x: np.asarray(x).nbytes)
    start = bytes(data).find(np.asarray(largest).tobytes()[:64])
    assert start > 0
    middle = start + np.asarray(largest).nbytes // 2
    data[middle:middle + 4] = bytes(b ^ 0xFF for b in data[middle:middle + 4])
    (copy / run_dir.CHECKPOINT).write_bytes(bytes(data))
    serialization.msgpack_restore(bytes(data))  # still a well-formed file
    return str(copy)


def test_a_checkpoint_with_flipped_array_bytes_is_refused(run, tmp_path):
    import sac_jax

    damaged = _damaged_copy(run[0], tmp_path)
    with pytest.raises(checkpoint.CheckpointError, match=r"damaged \(array \d+ does not match"):
        run_dir.load_checkpoint(damaged)
    with pytest.raises(checkpoint.CheckpointError, match="damaged"):
        sac_jax.load_policy(damaged)


def test_resume_from_a_damaged_checkpoint_ends_with_one_line_and_exit_2(run, tmp_path, capsys):
    from scripts import train as train_script

    damaged = _damaged_copy(run[0], tmp_path)
    assert train_script.main(["--resume", damaged]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: checkpoint {damaged}") and "damaged" in err, err
    assert "\n" not in err
