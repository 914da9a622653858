"""sac_jax.records_process.RecordsProcess: TensorBoard's records and curves.png written by a
child process, its failures raised in the parent as the exceptions they were, the parent
writing where no child can, and a child not used or left by its parent ending, its records
whole."""

import errno
import os
import subprocess
import sys

import numpy as np
import pytest

from sac_jax import plots, records_process
from sac_jax.records_process import RecordsProcess
from tests.test_train_script import tensorboard_scalars

PNG = b"\x89PNG\r\n\x1a\n"
HISTORY = [(1000, {"eval_return": -900.0}, np.array([-900.0, -1000.0]))]
POINTS = [(2000, {"eval_return": -500.0}, np.array([-400.0, -600.0])),
          (3000, {"eval_return": -175.0}, np.array([-150.0, -200.0]))]


def _curves(run_dir):
    """`write_curves`' arguments for a run of 2 seeds and 3 points."""
    steps = np.array([[1000, 2000, 3000]] * 2)
    returns = np.array([[-900.0, -400.0, -150.0], [-1000.0, -600.0, -200.0]])
    metrics = {"env_steps": steps, "eval_return": returns, "delivered_return": returns}
    return (str(run_dir), metrics, 3, "Pendulum-v1, preset test", -250.0)


def _write(records, run_dir, start=True):
    """A run's use of `records`: started (if `start`), its points added, TensorBoard's records
    closed, curves.png drawn, and the process closed."""
    try:
        if start:
            records.start()
        for point in POINTS:
            records.add_point(*point)
        records.close_tensorboard()
        records.write_curves(*_curves(run_dir))
    finally:
        records.close()


def _check(run_dir):
    """run_dir holds curves.png and TensorBoard's records of HISTORY and POINTS, each once."""
    assert (run_dir / "curves.png").read_bytes()[:8] == PNG
    found = tensorboard_scalars(run_dir / "tensorboard")
    assert [(step, value) for tag, step, value in found if tag == "eval_return/seed_1"] == [
        (1000, -1000.0), (2000, -600.0), (3000, -200.0)]


def test_a_started_process_writes_the_records_in_the_child(tmp_path, monkeypatch):
    monkeypatch.setattr(plots, "write_curves", lambda *args: 1 / 0)  # not in this process
    monkeypatch.setattr(records_process, "TensorBoard", lambda *args: 1 / 0)
    _write(RecordsProcess(str(tmp_path), HISTORY), tmp_path)
    _check(tmp_path)
    assert sorted(os.listdir(tmp_path)) == ["curves.png", "tensorboard"]


def test_the_child_imports_neither_jax_nor_anything_of_the_training_process():
    imports = ("import sys, sac_jax.records_process; "
               "print(sorted(m for m in ('jax', 'orbax', 'tensorboard', 'matplotlib') "
               "if m in sys.modules))")
    loaded = subprocess.run([sys.executable, "-c", imports], capture_output=True, text=True,
                            check=True).stdout
    assert loaded.strip() == "[]"


def test_without_a_child_to_write_this_process_writes(tmp_path, monkeypatch):
    """A process never started, one that could not start, and children killed before their
    first point, between two points and before drawing: every point is in TensorBoard's
    records once."""
    names = ("never", "unstartable", "killed_at_once", "killed_between", "killed_at_the_end")
    for name in names:
        (tmp_path / name).mkdir()
    _write(RecordsProcess(str(tmp_path / "never"), HISTORY), tmp_path / "never", start=False)

    def no_process(*args, **kwargs):
        raise OSError(errno.EAGAIN, "Resource temporarily unavailable")
    unstartable = RecordsProcess(str(tmp_path / "unstartable"), HISTORY)
    with monkeypatch.context() as patch:
        patch.setattr(subprocess, "Popen", no_process)
        unstartable.start()
    _write(unstartable, tmp_path / "unstartable", start=False)

    def kill(records):
        records._child.kill()
        records._child.wait()
    at_once = RecordsProcess(str(tmp_path / "killed_at_once"), HISTORY)
    at_once.start()
    kill(at_once)
    _write(at_once, tmp_path / "killed_at_once", start=False)

    between = RecordsProcess(str(tmp_path / "killed_between"), HISTORY)
    between.start()
    between.add_point(*POINTS[0])
    kill(between)
    between.add_point(*POINTS[1])
    between.close_tensorboard()
    between.write_curves(*_curves(tmp_path / "killed_between"))
    between.close()

    at_the_end = RecordsProcess(str(tmp_path / "killed_at_the_end"), HISTORY)
    at_the_end.start()
    for point in POINTS:
        at_the_end.add_point(*point)
    at_the_end.close_tensorboard()
    kill(at_the_end)
    at_the_end.write_curves(*_curves(tmp_path / "killed_at_the_end"))
    at_the_end.close()
    for name in names:
        _check(tmp_path / name)


def test_a_write_the_child_could_not_make_is_the_systems_error(tmp_path):
    curves = RecordsProcess(str(tmp_path), HISTORY)
    curves.start()
    try:
        curves.close_tensorboard()
        with pytest.raises(OSError) as error:
            curves.write_curves(*_curves(tmp_path / "missing"))
    finally:
        curves.close()
    assert error.value.errno == errno.ENOENT and error.value.strerror
    assert str(tmp_path / "missing" / "curves.png") in error.value.filename

    (tmp_path / "file").write_text("")  # a directory that cannot be made
    tensorboard = RecordsProcess(str(tmp_path / "file"), HISTORY)
    tensorboard.start()
    try:
        with pytest.raises(OSError) as error:
            for point in POINTS:
                tensorboard.add_point(*point)
            tensorboard.close_tensorboard()
        tensorboard.close_tensorboard()  # once failed, nothing more is tried
    finally:
        tensorboard.close()
    assert error.value.errno == errno.ENOTDIR and error.value.strerror
    assert str(tmp_path / "file") in error.value.filename


def test_any_other_failure_of_the_child_is_its_last_line(tmp_path):
    records = RecordsProcess(str(tmp_path))
    records.start()
    run_dir, metrics, points, title, threshold = _curves(tmp_path)
    del metrics["delivered_return"]
    try:
        records.close_tensorboard()
        with pytest.raises(RuntimeError, match=r"^curves.png: KeyError: 'delivered_return'$"):
            records.write_curves(run_dir, metrics, points, title, threshold)
    finally:
        records.close()
    assert os.listdir(tmp_path) == ["tensorboard"]  # and no curves.png, whole or in part


def test_a_child_runs_last_ends_when_not_used_and_ends_with_its_records_whole_if_orphaned(
        tmp_path):
    records = RecordsProcess(str(tmp_path))
    records.start()
    child = records._child
    assert os.getsid(child.pid) != os.getsid(0)  # a terminal's Ctrl-C does not reach it
    records.close_tensorboard()
    assert os.getpriority(os.PRIO_PROCESS, child.pid) == 19  # training's threads go first
    records.close()
    assert child.returncode is not None
    records = RecordsProcess(str(tmp_path), HISTORY)
    records.start()
    for point in POINTS:
        records.add_point(*point)
    records._child.stdin.close()  # as when its parent dies
    assert records._child.wait(timeout=120) == 0
    records._child = None
    assert [step for tag, step, _ in tensorboard_scalars(tmp_path / "tensorboard")
            if tag == "eval_return/seed_0"] == [1000, 2000, 3000]
    assert not (tmp_path / "curves.png").exists()
