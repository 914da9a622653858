"""scripts/render.py: a GIF with one frame per state of the episode at the requested size and
frame rate (Pendulum-v1 drawn with matplotlib; InvertedPendulum-v5 with MuJoCo's headless
renderer, in a subprocess so that it picks its OpenGL backend itself); an existing file is
kept; bad input ends with one line and a non-zero exit code, leaving the run directory as it
was."""

import ctypes.util
import os
import shutil
import subprocess
import sys

import imageio.v3 as iio
import mujoco
import numpy as np
import pytest

import envs
import jax
import sac_jax
from sac_jax import run_checkpoint
from scripts import render as render_script
from tests.saved_runs import (copied_run, fails_in_one_line, untrained,
                              with_planted_delivered_actor)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("runs")
    return {"pendulum": untrained(str(root / "pendulum"), "Pendulum-v1"),
            "cartpole": untrained(str(root / "cartpole"), "InvertedPendulum-v5")}


def _frames(path):
    return iio.imread(path, index=None)


def _red_pixels(frame):
    red, green, blue = (frame[..., i].astype(int) for i in range(3))
    return np.argwhere((red > 150) & (green < 100) & (blue < 100))


def test_pendulum_gif_frames_size_and_rate(runs, tmp_path, capsys):
    out = str(tmp_path / "swing.gif")
    argv = [runs["pendulum"], "--out", out, "--steps", "7", "--width", "160", "--height", "120"]
    assert render_script.main(argv) == 0
    assert capsys.readouterr().out.startswith(f"wrote {out}: 8 frames of 160x120 at 20 fps")
    frames = _frames(out)
    assert frames.shape == (8, 120, 160, 3)  # the initial state and 7 steps (no early end)
    assert iio.immeta(out)["duration"] == 50  # ms: 1 / dt of Pendulum-v1 = 20 fps
    assert not np.array_equal(frames[0], frames[-1])
    assert sorted(os.listdir(tmp_path)) == ["swing.gif"]  # no temporary file left


def test_policy_renders_the_delivered_or_the_last_actor(runs, tmp_path, capsys):
    """--policy best draws the delivered actor's episode, --policy last the last update's: each
    return printed is a rollout of that actor's own parameters, and their frames differ (the
    delivered actor is planted, half the last one's parameters)."""
    run = with_planted_delivered_actor(copied_run(runs["pendulum"], tmp_path))
    frames = {}
    for which in ("best", "last"):
        out = str(tmp_path / f"{which}.gif")
        argv = [run, "--out", out, "--steps", "12", "--width", "64", "--height", "48",
                "--policy", which]
        assert render_script.main(argv) == 0
        policy = sac_jax.load_policy(run, 0, which)
        _, total, _ = render_script.rollout(policy, policy.config.make_env(),
                                            jax.random.key(0), 12)
        assert capsys.readouterr().out.rstrip().endswith(f"return {total:.1f}")
        frames[which] = _frames(out)
    assert not np.array_equal(frames["best"], frames["last"])


def test_pendulum_drawing_convention():
    """θ = 0 is upright and θ = π/2 points left, as in Gymnasium's drawing."""
    up, left = render_script.pendulum_frames(np.array([0.0, np.pi / 2]), 100, 100, 0.05)
    # The pivot is at pixel (50, 50); the rod, 1 of the 2.6 units across, is 38 pixels long.
    (row, col), (top, _) = _red_pixels(up).mean(axis=0), _red_pixels(up).min(axis=0)
    assert abs(col - 50) < 1 and 25 < row < 40 and top < 15
    (row, col), (_, leftmost) = _red_pixels(left).mean(axis=0), _red_pixels(left).min(axis=0)
    assert abs(row - 50) < 1 and 25 < col < 40 and leftmost < 15


def test_default_output_and_no_overwrite_without_force(runs, capsys):
    out = os.path.join(runs["pendulum"], "episode.gif")
    assert render_script.main([runs["pendulum"], "--steps", "2"]) == 0
    assert _frames(out).shape[0] == 3
    with open(out, "ab") as f:
        f.write(b"mine")  # marks this file
    before = open(out, "rb").read()
    assert render_script.main([runs["pendulum"], "--steps", "4"]) == 2
    err = capsys.readouterr().err
    assert err.strip().endswith("already exists; use --force to replace it")
    assert open(out, "rb").read() == before
    assert render_script.main([runs["pendulum"], "--steps", "4", "--force"]) == 0
    assert _frames(out).shape[0] == 5
    os.remove(out)


def test_cartpole_gif_with_mujocos_renderer(runs, tmp_path):
    if not (os.environ.get("MUJOCO_GL") or ctypes.util.find_library("EGL")
            or ctypes.util.find_library("OSMesa")):
        pytest.skip("no headless OpenGL library (libEGL or libOSMesa) on this machine")
    out = str(tmp_path / "cartpole.gif")
    done = subprocess.run(
        [sys.executable, os.path.join(ROOT, "scripts", "render.py"), runs["cartpole"], "--out",
         out, "--steps", "5", "--width", "96", "--height", "64"],
        capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    steps = int(done.stdout.split(" steps of InvertedPendulum-v5")[0].rsplit(" ", 1)[1])
    frames = _frames(out)
    assert 1 <= steps <= 5 and frames.shape == (steps + 1, 64, 96, 3)
    lit = (frames.max(axis=-1) > 40).mean(axis=(1, 2))  # the rail, cart and pole on black
    assert np.all((lit > 0.02) & (lit < 0.5))


def test_no_opengl_context_is_one_line_naming_the_setting(runs, tmp_path, capsys, monkeypatch):
    def no_context(*args, **kwargs):
        raise mujoco.FatalError("an OpenGL platform library has not been loaded into this "
                                "process\nsecond line")

    monkeypatch.setattr(mujoco, "Renderer", no_context)
    with pytest.raises(render_script.MissingDependency, match="libegl1.*libosmesa6"):
        render_script.mujoco_renderer(envs.make("InvertedPendulum-v5"), 8, 8)
    out = str(tmp_path / "x.gif")
    assert render_script.main([runs["cartpole"], "--out", out, "--steps", "5"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "MUJOCO_GL" in err and "not been loaded" in err
    assert not os.path.exists(out)


def test_a_gl_backend_mujoco_cannot_load_is_one_line(runs, tmp_path):
    out = str(tmp_path / "x.gif")
    done = subprocess.run(
        [sys.executable, os.path.join(ROOT, "scripts", "render.py"), runs["cartpole"], "--out",
         out], capture_output=True, text=True, timeout=300,
        env=dict(os.environ, MUJOCO_GL="no-such-backend"))
    assert done.returncode == 1 and done.stderr.count("\n") == 1, done.stderr
    assert done.stderr.startswith("error: MUJOCO_GL='no-such-backend': importing mujoco failed")
    assert not os.path.exists(out)


def _fails(capsys, argv, code, message):
    fails_in_one_line(capsys, render_script.main, argv, code, message)


@pytest.mark.parametrize("case, message", [
    ("missing run", "no such run directory"),
    ("missing checkpoint", "not found"),
    ("bad seed", "seed=3: run"),
    ("bad extension", "unknown format .png"),
    ("no directory", "no such directory"),
])
def test_bad_input_writes_nothing(runs, tmp_path, capsys, case, message):
    run = str(tmp_path / "copy")
    shutil.copytree(runs["pendulum"], run)
    argv = [run]
    if case == "missing run":
        argv = [str(tmp_path / "nowhere")]
    elif case == "missing checkpoint":
        shutil.rmtree(run_checkpoint.directory(run))
    elif case == "bad seed":
        argv += ["--seed", "3"]
    elif case == "bad extension":
        argv += ["--out", str(tmp_path / "x.png")]
    elif case == "no directory":
        argv += ["--out", str(tmp_path / "no" / "x.gif")]
    before = sorted(os.listdir(run))
    _fails(capsys, argv, 2, message)
    assert sorted(os.listdir(run)) == before and sorted(os.listdir(tmp_path)) == ["copy"]


@pytest.mark.parametrize("flag", ["--steps", "--fps", "--width", "--height"])
def test_non_positive_values(runs, capsys, flag):
    _fails(capsys, [runs["pendulum"], flag, "0"], 2, f"{flag}=0: must be a positive integer")


def test_episode_seed_out_of_range(runs, capsys):
    _fails(capsys, [runs["pendulum"], "--episode-seed", "-1"], 2,
           "--episode-seed=-1: must be an integer in [0, 2**32)")


def test_mp4_without_a_video_encoder(runs, tmp_path, capsys, monkeypatch):
    for module in ("imageio_ffmpeg", "av"):
        monkeypatch.setitem(sys.modules, module, None)  # import -> ImportError
    _fails(capsys, [runs["pendulum"], "--out", str(tmp_path / "x.mp4")], 1,
           "pip install imageio-ffmpeg")
    assert os.listdir(tmp_path) == []


def test_mp4(runs, tmp_path):
    if render_script._video_writer_missing(".mp4"):
        pytest.skip("no MP4 encoder installed (imageio-ffmpeg or PyAV)")
    out = str(tmp_path / "swing.mp4")
    assert render_script.main([runs["pendulum"], "--out", out, "--steps", "9"]) == 0
    assert _frames(out).shape == (10, 320, 480, 3)


