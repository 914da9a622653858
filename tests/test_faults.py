"""Fault injection: every fault a user can meet around a run's files and signals ends in one
line naming it and a non-zero exit (or, where the run can go on, one warning and the run going
on), loses nothing already saved, and leaves nothing half-made that blocks a rerun.

    fault                                   what the user gets
    damaged checkpoint (flipped bytes,      train --resume, evaluate, render: exit 2, one line
      truncated, garbage)                     naming it and the intact step before it; that
                                              step loads only when asked for
    unreadable position record              refused as unexpected metadata
    a step left half-written by a kill      not a step; the next write removes it
    full disk while writing a checkpoint    exit 1, one line; the last checkpoint kept whole,
                                              no half-written step (patched writer; a real
                                              tmpfs where the tests may mount one)
    full disk under TensorBoard's records   exit 1, one line; a new run without a checkpoint
                                              leaves no directory
    full disk writing the result files      exit 1, one line; --resume writes them
    --out that cannot be created            exit 2, one line, nothing made
    unwritable --cache-dir                  one warning; trains on without the cache
    damaged traced program in the cache     one warning; traced again; the run finishes
    unwritable render output                exit 2, one line, checked before rendering and
                                              again at the write; no file, no temporary file
    read-only run directory for evaluate    evaluated; nothing written anywhere
    second SIGINT (also during the final    exit 130, one line; the checkpoint on disk whole
      save)
"""

import errno
import json
import math
import os
import shutil
import signal
import subprocess

import jax
import pytest

import sac_jax
from sac_jax import checkpoint, compilation_cache, metric_writers, run_checkpoint
from sac_jax import run as training
from sac_jax.position import Position
from scripts import evaluate as evaluate_script
from scripts import render as render_script
from scripts import sweep as sweep_script
from scripts import train as train_script
from tests.saved_runs import (SMALL_RUN, checkpoint_header, copied_run, damage_checkpoint,
                              fails_in_one_line, newest_checkpoint, two_checkpoints)
from tests.signals import interrupted_main

AS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """(run directory, state): Pendulum-v1, 2 seeds, checkpoints of steps 0 and 800."""
    return two_checkpoints(str(tmp_path_factory.mktemp("faults") / "run"))


# ---------------------------------------------------------------- damaged checkpoints
@pytest.mark.parametrize("how, message", [("flip", r"damaged \(array \d+ does not match"),
                                          ("truncate", r"damaged \(state/\S+ holds \d+ bytes"),
                                          ("garbage", "unreadable")])
def test_a_damaged_checkpoint_is_refused_naming_it_and_the_intact_step_before(
        run, tmp_path, how, message):
    damaged = copied_run(run[0], tmp_path)
    damage_checkpoint(damaged, how)
    where = newest_checkpoint(damaged)
    with pytest.raises(checkpoint.CheckpointError, match=message) as error:
        run_checkpoint.load_checkpoint(damaged)
    text = str(error.value)
    assert text.startswith(f"checkpoint {where}: ") and "\n" not in text
    assert text.endswith("the checkpoint of step 0 before it is intact: continue from it with "
                         f"scripts/train.py --resume {damaged} --resume-step 0")
    with pytest.raises(checkpoint.CheckpointError, match=message):
        sac_jax.load_policy(damaged)
    _, _, first, _ = run_checkpoint.load_checkpoint(damaged, step=0)  # asked for: it loads
    assert int(first.buffer.size) == 0


@pytest.mark.parametrize("script, argv", [
    (train_script, ["--resume"]),
    (evaluate_script, ["--which", "ours"]),
    (render_script, ["--out", "OUT"]),
], ids=["train", "evaluate", "render"])
@pytest.mark.parametrize("how", ["flip", "truncate", "garbage"])
def test_each_script_refuses_a_damaged_checkpoint_in_one_line_with_exit_2(
        run, tmp_path, capsys, script, argv, how):
    damaged = copied_run(run[0], tmp_path)
    damage_checkpoint(damaged, how)
    before = sorted(os.listdir(tmp_path))
    argv = [str(tmp_path / "x.gif") if a == "OUT" else a for a in argv]
    argv = ["--resume", damaged] if script is train_script else [damaged] + argv
    fails_in_one_line(capsys, script.main, argv, 2,
                      f"error: checkpoint {newest_checkpoint(damaged)}: ")
    assert sorted(os.listdir(tmp_path)) == before  # no GIF, nothing else


def test_a_resume_from_the_intact_step_asked_for_trains_on(run, tmp_path, capsys):
    damaged = copied_run(run[0], tmp_path)
    damage_checkpoint(damaged, "flip")
    assert train_script.main(["--resume", damaged, "--resume-step", "0"]) == 0, (
        capsys.readouterr().err)
    assert run_checkpoint.saved_steps(damaged)[-1] == 6000


def test_a_position_record_that_cannot_be_read_is_unexpected_metadata(run, tmp_path):
    copy = copied_run(run[0], tmp_path)
    path = os.path.join(newest_checkpoint(copy), "meta", "metadata")
    header = checkpoint_header(newest_checkpoint(copy))
    header["meta"]["position"]["walls"] = {"2000": "soon"}
    with open(path, "w") as f:
        json.dump(header, f)
    with pytest.raises(checkpoint.CheckpointError, match="unexpected metadata"):
        run_checkpoint.load_checkpoint(copy)


def test_a_step_left_half_written_is_neither_listed_nor_kept(run, tmp_path):
    """A process killed while orbax writes leaves `<step>.orbax-checkpoint-tmp`: it is not a
    step, and the next write removes it."""
    copy = copied_run(run[0], tmp_path)
    partial = os.path.join(run_checkpoint.directory(copy), "900.orbax-checkpoint-tmp")
    shutil.copytree(newest_checkpoint(copy), partial)
    assert run_checkpoint.saved_steps(copy) == [0, 800]
    run_checkpoint.save_checkpoint(copy, run[1], Position(chunks_done=4, env_steps=1000))
    assert sorted(os.listdir(run_checkpoint.directory(copy))) == ["1000", "800"]


# ---------------------------------------------------------------- full disk
def _bytes_under(path):
    return sum(os.path.getsize(os.path.join(root, name))
               for root, _, names in os.walk(path) for name in names)


def test_a_full_disk_leaves_the_earlier_steps_and_nothing_half_written(run, tmp_path):
    """On a tmpfs with room for one checkpoint but not two (mounting needs root; the
    patched-writer test below runs everywhere), the second checkpoint is refused in one line
    before anything is written, and the first stays whole."""
    out, saved = run
    need = sum(x.nbytes for x in run_checkpoint._stored(saved)[0]) + checkpoint.ROOM_FOR_METADATA
    size = need + _bytes_under(newest_checkpoint(out)) // 2  # one fits; a second does not
    small = tmp_path / "small"
    small.mkdir()
    mount = ["mount", "-t", "tmpfs", "-o", f"size={-(-size // 4096) * 4096}", "tmpfs", str(small)]
    if subprocess.run(mount, capture_output=True).returncode != 0:
        pytest.skip("cannot mount a tmpfs here")
    try:
        run_dir = str(small / "run")
        os.makedirs(run_dir)
        for name in ("config.json", "run.json"):
            shutil.copy(os.path.join(out, name), run_dir)
        run_checkpoint.save_checkpoint(run_dir, saved, Position(chunks_done=1, env_steps=1))
        with pytest.raises(run_checkpoint.CheckpointWriteError,
                           match=r"^checkpoint of step 2 in .* could not be written \(No space "
                                 r"left on device: the checkpoint needs up to [\d.]+ MB, [\d.]+ MB "
                                 r"are free\)$"):
            run_checkpoint.save_checkpoint(run_dir, saved, Position(chunks_done=2, env_steps=2))
        assert os.listdir(run_checkpoint.directory(run_dir)) == ["1"]
        assert run_checkpoint.load_checkpoint(run_dir)[3].env_steps == 1  # whole
    finally:
        subprocess.run(["umount", str(small)], check=False)


def test_a_checkpoint_without_room_on_the_disk_is_refused_before_anything_is_written(
        run, tmp_path, monkeypatch):
    """The free-space check runs everywhere (the tmpfs test above needs root): with a byte
    less free than the checkpoint may take, the write is refused in one line and the earlier
    step stays the only one, whole."""
    out, saved = run
    copy = copied_run(out, tmp_path)
    steps = run_checkpoint.saved_steps(copy)
    need = sum(x.nbytes for x in run_checkpoint._stored(saved)[0]) + checkpoint.ROOM_FOR_METADATA
    usage = shutil.disk_usage(copy)
    monkeypatch.setattr(checkpoint.shutil, "disk_usage",
                        lambda path: usage._replace(free=need - 1))
    with pytest.raises(run_checkpoint.CheckpointWriteError,
                       match=rf"^checkpoint of step {steps[-1] + 200} in .* could not be written "
                             rf"\(No space left on device: the checkpoint needs up to "
                             rf"{need / 1e6:.1f} MB, {(need - 1) / 1e6:.1f} MB are free\)$"):
        run_checkpoint.save_checkpoint(copy, saved, Position(chunks_done=9,
                                                             env_steps=steps[-1] + 200))
    assert run_checkpoint.saved_steps(copy) == steps
    run_checkpoint.load_checkpoint(copy)  # whole: it loads


def test_a_checkpoint_that_cannot_be_written_ends_the_run_in_one_line(tmp_path, capsys,
                                                                      monkeypatch):
    """A full disk at the second checkpoint (the writer patched to fail as orbax does, leaving
    a half-written step): exit 1, one line naming the step and the reason and the checkpoint
    kept, which stays whole; nothing half-written is left."""
    save = checkpoint.save

    def full_disk(directory, step, tree, meta):
        if step > 2000:
            os.makedirs(os.path.join(directory, f"{step}.orbax-checkpoint-tmp", "state"))
            raise OSError(28, "No space left on device")
        save(directory, step, tree, meta)

    monkeypatch.setattr(checkpoint, "save", full_disk)
    monkeypatch.setattr(run_checkpoint, "MIN_INTERVAL_S", 0.0)  # a write at every point
    out = str(tmp_path / "full")
    assert train_script.main(SMALL_RUN + ["--out", out]) == 1
    err = capsys.readouterr().err.strip()
    assert err == (f"error: checkpoint of step 3000 in {run_checkpoint.directory(out)} could not "
                   "be written (No space left on device); the last checkpoint written (step "
                   f"2000) is kept: continue with --resume {out}"), err
    assert os.listdir(run_checkpoint.directory(out)) == ["2000"]
    run_checkpoint.load_checkpoint(out)  # whole: it loads


FULL_DISK_UNDER_TENSORBOARD = """\
import errno, os
from sac_jax import metric_writers

def full_disk(self, *args):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

metric_writers.TensorBoard._write = full_disk
"""
"""A `sitecustomize` module: every Python process started with it on its path fails to write
TensorBoard's events as a full disk would."""


def test_tensorboard_records_that_cannot_be_written_end_a_new_run_leaving_nothing(
        tmp_path, capsys, monkeypatch):
    """A full disk under TensorBoard's event file at the first point, met by the records
    process (`sac_jax.records_process`, given a `sitecustomize` that fails the write; its
    failure reaches the run at a later point or at the end): exit 1, one line naming it; a new
    run with no checkpoint yet leaves no directory, so --out is free again."""
    (tmp_path / "site").mkdir()
    (tmp_path / "site" / "sitecustomize.py").write_text(FULL_DISK_UNDER_TENSORBOARD)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
        [str(tmp_path / "site")] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
    monkeypatch.setattr(run_checkpoint, "MIN_INTERVAL_S", 1e9)  # no checkpoint before the end
    out = str(tmp_path / "full")
    assert train_script.main(SMALL_RUN + ["--out", out]) == 1
    err = capsys.readouterr().err
    assert err == (f"error: TensorBoard's records could not be written: No space left on "
                   f"device; {out} removed\n"), err
    assert not os.path.exists(out)


def test_result_files_that_cannot_be_written_keep_the_final_checkpoint_to_resume(
        tmp_path, capsys, monkeypatch):
    """A full disk as the result files are written after the last checkpoint: exit 1, one
    line naming the file and the checkpoint kept; --resume then writes the result files."""
    write_summary = metric_writers.write_summary

    def full_disk(path, summary):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), os.path.join(path, "summary.json"))

    monkeypatch.setattr(metric_writers, "write_summary", full_disk)
    out = str(tmp_path / "full")
    assert train_script.main(SMALL_RUN + ["--out", out]) == 1
    err = capsys.readouterr().err
    last = run_checkpoint.saved_steps(out)[-1]
    assert err == (f"error: the result files could not be written ({out}/summary.json): No "
                   f"space left on device; the last checkpoint written (step {last}) is kept: "
                   f"continue with --resume {out}\n"), err
    assert not os.path.exists(os.path.join(out, "summary.json"))
    monkeypatch.setattr(metric_writers, "write_summary", write_summary)
    assert train_script.main(["--resume", out]) == 0
    assert json.load(open(os.path.join(out, "summary.json")))["status"] == "finished"


def test_a_checkpoint_that_cannot_be_written_ends_a_sweep_in_one_line(tmp_path, capsys,
                                                                      monkeypatch):
    """As for scripts/train.py (it had ended with a traceback); the line names the program
    and the sweep directory to resume."""
    save = checkpoint.save

    def full_disk(directory, step, tree, meta):
        if step > 2000:
            raise OSError(28, "No space left on device")
        save(directory, step, tree, meta)

    monkeypatch.setattr(checkpoint, "save", full_disk)
    monkeypatch.setattr(run_checkpoint, "MIN_INTERVAL_S", 0.0)
    out = str(tmp_path / "sweep")
    assert sweep_script.main(SMALL_RUN + ["--set", "actor_lr=1e-3,3e-4", "--out", out]) == 1
    err = capsys.readouterr().err.strip()
    program = os.path.join(out, "programs", "0")
    assert err == (f"error: program 1: checkpoint of step 3000 in "
                   f"{run_checkpoint.directory(program)} could not be written (No space left on "
                   "device); the last checkpoint written (step 2000) is kept: continue with "
                   f"--resume {out}"), err
    assert os.listdir(run_checkpoint.directory(program)) == ["2000"]


def test_the_background_writer_reraises_a_failed_write_in_one_line(run, tmp_path):
    (tmp_path / "file").write_text("not a directory")
    writer = run_checkpoint.CheckpointWriter(str(tmp_path / "file" / "run"), min_interval_s=0)
    writer.save(run[1], Position(chunks_done=3, env_steps=7))
    with pytest.raises(run_checkpoint.CheckpointWriteError,
                       match=r"^checkpoint of step 7 in .*/file/run/checkpoints could not be "
                             r"written \(") as error:
        writer.close()
    assert "\n" not in str(error.value)


# ---------------------------------------------------------------- --out and the caches
def test_an_out_that_cannot_be_created_ends_with_one_line_and_leaves_nothing(tmp_path, capsys):
    """`--out` under a regular file (so even root cannot create it): exit 2, one line."""
    (tmp_path / "file").write_text("mine")
    out = tmp_path / "file" / "run"
    assert train_script.main(["--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"error: --out={out}: {tmp_path / 'file'} is not a directory", err
    assert sorted(os.listdir(tmp_path)) == ["file"]


@pytest.fixture
def cache_dir(tmp_path):
    """A compilation cache directory of the test's own; the session's is restored after."""
    before = jax.config.jax_compilation_cache_dir
    yield str(tmp_path / "cache")
    jax.config.update("jax_compilation_cache_dir", before)
    jax.config.update("jax_enable_compilation_cache", True)


def test_an_unwritable_cache_directory_trains_on_without_it(tmp_path, recwarn, cache_dir):
    """One warning naming the directory; the run finishes and writes its results, with both
    caches off even where JAX already had a directory (as from $JAX_COMPILATION_CACHE_DIR)."""
    (tmp_path / "file").write_text("mine")
    cache = str(tmp_path / "file" / "cache")
    out = str(tmp_path / "run")
    jax.config.update("jax_compilation_cache_dir", cache_dir)  # as JAX reads it from the env
    assert train_script.main(SMALL_RUN + ["--cache-dir", cache, "--out", out]) == 0
    messages = [str(w.message) for w in recwarn if "compilation cache" in str(w.message)]
    assert messages == [f"compilation cache {cache}: not writable (Not a directory); "
                        "compiling without it"], messages
    assert os.path.exists(os.path.join(out, "summary.json"))
    assert compilation_cache.program_directory() is None
    assert not os.path.exists(os.path.join(cache_dir, "programs"))  # no traced program kept


def test_no_cache_turns_off_a_cache_jax_was_given(tmp_path, cache_dir):
    jax.config.update("jax_compilation_cache_dir", cache_dir)  # as JAX reads it from the env
    assert train_script.main(SMALL_RUN + ["--no-cache", "--out", str(tmp_path / "run")]) == 0
    assert compilation_cache.active_directory() is None
    assert not os.path.exists(os.path.join(cache_dir, "programs"))  # no traced program kept


def test_a_damaged_cached_program_is_traced_again_with_one_warning(tmp_path, cache_dir,
                                                                    recwarn):
    """Bytes flipped in the middle of each traced program of a run (under
    `<cache-dir>/programs`) once ended the next run with "SmallVector unable to grow": now
    it gets one warning per damaged file, traces it again, and finishes; likewise each
    damaged executable (stored where this process compiled it, not where the session's JAX
    cache supplied it) is compiled again."""
    training.compiled_program.cache_clear()  # else this process keeps the programs it loaded
    assert train_script.main(SMALL_RUN + ["--cache-dir", cache_dir,
                                          "--out", str(tmp_path / "first")]) == 0
    programs = os.path.join(cache_dir, "programs")
    files = [os.path.join(programs, name) for name in os.listdir(programs)]
    assert files
    for path in files:
        data = bytearray(open(path, "rb").read())
        middle = len(data) // 2
        data[middle:middle + 8] = bytes(b ^ 0xFF for b in data[middle:middle + 8])
        with open(path, "wb") as f:
            f.write(bytes(data))
    recwarn.clear()
    training.compiled_program.cache_clear()
    assert train_script.main(SMALL_RUN + ["--cache-dir", cache_dir,
                                          "--out", str(tmp_path / "second")]) == 0
    messages = sorted(str(w.message) for w in recwarn if "cached " in str(w.message))
    expected = [f"cached program {path} is damaged (checksum mismatch); tracing it again"
                if path.endswith(".jaxexport") else
                f"cached executable {path} is damaged (checksum mismatch); compiling it again"
                for path in files]
    assert messages == sorted(expected), messages
    assert os.path.exists(os.path.join(tmp_path, "second", "summary.json"))


# ---------------------------------------------------------------- render and evaluate output
def _reason(how: str) -> str:
    """What render.py says of a directory blocked by `_block(directory, how)`."""
    if how == "missing":
        return "no such directory"
    return "is not a directory" if AS_ROOT else "is not writable (permission denied)"


def _block(directory, how: str) -> None:
    """Makes `directory` impossible to write a file in, `how` = "read-only" (chmod 0o500; as
    root, whom chmod does not stop, replaced by a regular file instead, which stops root too)
    or "missing" (removed); checks that a write there really fails."""
    if how == "missing" or AS_ROOT:
        shutil.rmtree(directory)
        if how != "missing":
            directory.write_text("a regular file\n")
    else:
        directory.chmod(0o500)
    with pytest.raises(OSError):
        open(directory / "probe.gif", "wb")


@pytest.fixture
def out_dir(tmp_path):
    """A directory for --out; its write permission is restored after the test."""
    directory = tmp_path / "out"
    directory.mkdir()
    yield directory
    if directory.is_dir():
        directory.chmod(0o700)


def _fails_writing(capsys, argv, out, reason):
    """render.py on `argv` exits with 2 and one line on stderr naming `out` and `reason`."""
    result = render_script.main(argv)
    err = capsys.readouterr().err
    assert result == 2 and err.count("\n") == 1, err
    assert err.startswith(f"error: --out={out}: cannot be written: ") and reason in err, err


@pytest.mark.parametrize("how", ["read-only", "missing"])
def test_an_unwritable_render_output_is_refused_before_rendering(run, out_dir, capsys,
                                                                 monkeypatch, how):
    _block(out_dir, how)
    monkeypatch.setattr(render_script, "rollout",
                        lambda *args, **kwargs: pytest.fail("rendered before refusing"))
    out = str(out_dir / "x.gif")
    _fails_writing(capsys, [run[0], "--out", out], out, _reason(how))
    assert not os.path.lexists(out)


@pytest.mark.parametrize("how", ["read-only", "missing"])
def test_a_render_output_directory_lost_while_rendering(run, out_dir, capsys, monkeypatch, how):
    """The directory is checked before rendering, and changes meanwhile: the write fails with
    one line naming the output and why, exit 2, and no file is left."""
    drawn = render_script.pendulum_frames

    def draw_then_block(*args, **kwargs):
        frames = drawn(*args, **kwargs)
        _block(out_dir, how)
        return frames

    monkeypatch.setattr(render_script, "pendulum_frames", draw_then_block)
    out = str(out_dir / "x.gif")
    _fails_writing(capsys, [run[0], "--out", out, "--steps", "2"], out, _reason(how))
    assert not os.path.lexists(out)
    if os.path.isdir(out_dir):
        out_dir.chmod(0o700)
        assert os.listdir(out_dir) == []


def test_a_failed_render_write_leaves_no_temporary_file(run, out_dir, capsys, monkeypatch):
    """A write that fails once the temporary file is complete (here a full disk when it is
    linked to --out) removes it: the directory is left as it was."""
    def full_disk(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "link", full_disk)
    out = str(out_dir / "x.gif")
    fails_in_one_line(capsys, render_script.main, [run[0], "--out", out, "--steps", "2"], 2,
                      "cannot be written: No space left")
    assert os.listdir(out_dir) == []


def _files(path):
    """{relative name: (bytes, mtime in ns)} of every file under `path`."""
    found = {}
    for directory, _, names in os.walk(path):
        for name in names:
            full = os.path.join(directory, name)
            with open(full, "rb") as f:
                found[os.path.relpath(full, path)] = (f.read(), os.stat(full).st_mtime_ns)
    return found


def test_evaluate_writes_nothing(run, tmp_path, capsys):
    """evaluate.py has no output file: a run directory made read-only (which stops anyone but
    root) is evaluated, and every file in it and beside it is left as it was."""
    path = copied_run(run[0], tmp_path)
    before = _files(tmp_path)
    modes = {p: os.stat(p).st_mode
             for p in [path] + [os.path.join(tmp_path, name) for name in before]}
    for p in modes:
        os.chmod(p, 0o555 if os.path.isdir(p) else 0o444)
    try:
        assert evaluate_script.main([path, "--which", "ours", "--episodes", "2", "--json"]) == 0
    finally:
        for p, mode in modes.items():
            os.chmod(p, mode)
    assert json.loads(capsys.readouterr().out)["episodes"] == 2
    assert _files(tmp_path) == before


# ---------------------------------------------------------------- signals
def test_a_second_sigint_stops_at_once_with_one_line(tmp_path, capsys, monkeypatch):
    """Two signals at the first evaluation point, before any checkpoint is due: the second
    ends the run where it is, with one line saying that none was written, exit 130 and no
    traceback. (A second signal while a checkpoint is written: the test below.)"""
    monkeypatch.setattr(run_checkpoint, "MIN_INTERVAL_S", 1e9)  # only the run's end is due
    out = str(tmp_path / "twice")
    code = interrupted_main(train_script, SMALL_RUN + ["--out", out], signals=2)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 130, err
    assert err[-1] == "error: SIGINT again: stopped at once; no checkpoint was written", err
    assert "Traceback" not in "".join(err)
    assert run_checkpoint.saved_steps(out) == []


def test_a_second_sigint_during_the_final_save_stops_with_one_line_and_a_whole_checkpoint(
        tmp_path, capsys, monkeypatch):
    """The first SIGINT stops the run at its first point; the second comes while the final
    checkpoint is being written: one line, exit 130, and the checkpoint, whose write the
    process waits for, is whole."""
    save = checkpoint.save

    def interrupted_save(directory, step, tree, meta):
        os.kill(os.getpid(), signal.SIGINT)
        save(directory, step, tree, meta)

    monkeypatch.setattr(checkpoint, "save", interrupted_save)
    out = str(tmp_path / "final")
    code = interrupted_main(train_script, SMALL_RUN + ["--out", out], signals=1)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 130, err
    assert err[-1] == ("error: SIGINT again: stopped at once; the last checkpoint written (step "
                       f"2000) is kept: continue with --resume {out}"), err
    assert run_checkpoint.saved_steps(out) == [2000]
    run_checkpoint.load_checkpoint(out)  # whole: it loads


# ---------------------------------------------------------------- memory
def test_a_run_out_of_device_memory_ends_in_one_line_and_leaves_nothing(tmp_path, capsys):
    """Replay buffers the device cannot allocate (the memory check overridden): XLA's
    RESOURCE_EXHAUSTED is one line naming it and the flags that shrink the run, exit 1, and
    the new run's directory, which holds no checkpoint, is removed. Each seed's observations
    take 24 GB (2 x 10^9 slots of Pendulum-v1's 3 float32), and there are enough seeds for that
    one array to be twice this machine's memory, an allocation Linux refuses outright (where
    it is not set to grant every one: vm.overcommit_memory 1)."""
    with open("/proc/sys/vm/overcommit_memory") as f:
        if f.read().strip() == "1":
            pytest.skip("every allocation is granted here: the run would be killed instead")
    memory_bytes = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    seeds = max(2, math.ceil(2 * memory_bytes / 24e9))
    out = str(tmp_path / "huge")
    assert train_script.main(SMALL_RUN + ["--seeds", str(seeds), "--buffer-size", "2000000000",
                                          "--no-memory-check", "--out", out]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: out of memory on cpu (Out of memory "
                                                   "allocating "), err
    assert err.endswith(f": lower --buffer-size or --seeds; {out} removed\n"), err
    assert os.listdir(tmp_path) == []
