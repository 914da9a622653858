"""sac_jax.plots.CurvesProcess: curves.png drawn by a child process, its failures raised in the
parent as the exceptions they were, the parent drawing where no child can, and a child not used
or left by its parent ending."""

import errno
import os
import subprocess

import numpy as np
import pytest

from sac_jax import plots

PNG = b"\x89PNG\r\n\x1a\n"


def _arguments(run_dir):
    """`write_curves`' arguments for a run of 2 seeds and 3 points."""
    steps = np.array([[1000, 2000, 3000]] * 2)
    returns = np.array([[-900.0, -400.0, -150.0], [-1000.0, -600.0, -200.0]])
    metrics = {"env_steps": steps, "eval_return": returns, "delivered_return": returns}
    return (str(run_dir), metrics, 3, "Pendulum-v1, preset test", -250.0)


def test_a_started_process_draws_the_curves_in_the_child(tmp_path, monkeypatch):
    monkeypatch.setattr(plots, "write_curves", lambda *args: 1 / 0)  # not in this process
    curves = plots.CurvesProcess()
    curves.start()
    try:
        curves.write_curves(*_arguments(tmp_path))
    finally:
        curves.close()
    assert (tmp_path / "curves.png").read_bytes()[:8] == PNG
    assert os.listdir(tmp_path) == ["curves.png"]


def test_without_a_child_to_draw_this_process_draws(tmp_path, monkeypatch):
    """A process never started, one that could not start, and a child killed before it drew."""
    for name in ("never", "unstartable", "killed"):
        (tmp_path / name).mkdir()
    never = plots.CurvesProcess()
    never.write_curves(*_arguments(tmp_path / "never"))
    never.close()

    def no_process(*args, **kwargs):
        raise OSError(errno.EAGAIN, "Resource temporarily unavailable")
    with monkeypatch.context() as patch:
        patch.setattr(subprocess, "Popen", no_process)
        unstartable = plots.CurvesProcess()
        unstartable.start()
    unstartable.write_curves(*_arguments(tmp_path / "unstartable"))
    unstartable.close()

    killed = plots.CurvesProcess()
    killed.start()
    killed._child.kill()
    killed._child.wait()
    killed.write_curves(*_arguments(tmp_path / "killed"))
    killed.close()
    for name in ("never", "unstartable", "killed"):
        assert (tmp_path / name / "curves.png").read_bytes()[:8] == PNG


def test_a_write_the_child_could_not_make_is_the_systems_error(tmp_path):
    curves = plots.CurvesProcess()
    curves.start()
    with pytest.raises(OSError) as error:
        curves.write_curves(*_arguments(tmp_path / "missing"))
    curves.close()
    assert error.value.errno == errno.ENOENT and error.value.strerror
    assert str(tmp_path / "missing" / "curves.png") in error.value.filename


def test_any_other_failure_of_the_child_is_its_last_line(tmp_path):
    curves = plots.CurvesProcess()
    curves.start()
    run_dir, metrics, points, title, threshold = _arguments(tmp_path)
    del metrics["delivered_return"]
    with pytest.raises(RuntimeError, match=r"^curves.png: KeyError: 'delivered_return'$"):
        curves.write_curves(run_dir, metrics, points, title, threshold)
    curves.close()
    assert os.listdir(tmp_path) == []


def test_a_child_not_used_is_ended_and_one_whose_parent_is_gone_ends_alone(tmp_path):
    curves = plots.CurvesProcess()
    curves.start()
    child = curves._child
    assert os.getsid(child.pid) != os.getsid(0)  # a terminal's Ctrl-C does not reach it
    curves.close()
    assert child.returncode is not None
    curves = plots.CurvesProcess()
    curves.start()
    curves._child.stdin.close()  # as when its parent dies
    assert curves._child.wait(timeout=120) == 0
    curves.close()
