"""The `sac-jax` command (scripts/console.py, installed as sac_jax_scripts.console): each command
runs its script with the flags given; --help lists the commands; a missing or unknown command
is one line and exit 2; nothing heavy is imported before the command is read, so that
scripts/render.py still chooses MuJoCo's OpenGL backend; pyproject.toml installs every package
and no top-level `scripts`."""

import ctypes.util
import os
import shutil
import subprocess
import sys
import sysconfig

import pytest

from scripts import console

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _exits(argv) -> int:
    with pytest.raises(SystemExit) as exit_:
        console.main(argv)
    return exit_.value.code


def test_help_lists_the_commands(capsys):
    assert _exits(["--help"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: sac-jax COMMAND [FLAGS]")
    listed = [line.split()[0] for line in out.split("commands:\n")[1].split("\n\n")[0].splitlines()]
    assert listed == ["train", "evaluate", "render", "sweep"]


@pytest.mark.parametrize("argv, message", [
    ([], "missing command"),
    (["trian"], "unknown command 'trian'"),
    (["--preset", "fast"], "unknown command '--preset'"),
])
def test_a_missing_or_unknown_command_is_one_line(capsys, argv, message):
    saved = list(sys.argv)
    assert _exits(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1, captured.err
    assert captured.err.startswith(f"error: {message}")
    assert "train, evaluate, render, sweep" in captured.err
    assert sys.argv == saved


@pytest.mark.parametrize("name", ["train", "evaluate", "render", "sweep"])
def test_each_command_is_its_script(capsys, name):
    """`sac-jax NAME --help` is the script's own --help, under the name `sac-jax NAME`; sys.argv
    is restored after."""
    saved = list(sys.argv)
    assert _exits([name, "--help"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: sac-jax {name} [-h]")
    script = sys.modules[f"scripts.{name}"]
    assert script.__doc__.splitlines()[0].rstrip(".") in " ".join(out.split())
    assert sys.argv == saved


def test_the_flags_reach_the_script(tmp_path, capsys):
    assert _exits(["evaluate", str(tmp_path / "nowhere"), "--episodes", "2"]) == 2
    err = capsys.readouterr().err
    assert err == f"error: {tmp_path / 'nowhere'}: no such run directory\n"


CORES = len(os.sched_getaffinity(0))


def _python(code: str, env=None) -> str:
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=300, env=env)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


@pytest.mark.parametrize("command, flags, devices", [
    ("train", "'--seeds', '4', '--out', 'README.md'", 4 if CORES >= 4 else min(2, CORES)),
    ("train", "'--seeds', '1', '--out', 'README.md'", 1),
    ("sweep", "'--seeds', '0'", CORES)])
def test_the_launcher_gives_the_training_scripts_a_cpu_device_per_core(command, flags, devices):
    """As when run as files: `sac-jax train --seeds 16` on a CPU splits its seeds over the
    cores, a device each, only as many as divide the seeds (the launcher had left one device:
    half the speed, and other compiled programs), and XLA's flags are the scripts'
    (`compilation_cache.sequential_cpu_scheduler`). Each command is refused (an existing --out,
    --seeds 0) after the devices were set."""
    from sac_jax.compilation_cache import SEQUENTIAL_CPU_SCHEDULER

    code = ("import atexit, os, sys, jax; from scripts import console; "
            "atexit.register(lambda: print('devices', len(jax.devices()), "
            "os.environ.get('XLA_FLAGS'))); "
            f"sys.argv = ['sac-jax', '{command}', {flags}]; console.main()")
    env = dict(os.environ, JAX_NUM_CPU_DEVICES="-1", JAX_PLATFORMS="cpu")
    env.pop("XLA_FLAGS", None)
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=300, env=env)
    assert done.returncode == 2, done.stderr
    assert done.stdout.strip().splitlines()[-1] == (f"devices {devices} "
                                                    f"{SEQUENTIAL_CPU_SCHEDULER}")


def test_the_launcher_imports_nothing_heavy():
    heavy = ("mujoco", "sac_jax", "envs", "jax", "tyro", "numpy")
    code = f"import sys; import scripts.console; print([m for m in {heavy} if m in sys.modules])"
    assert _python(code) == "[]"


def test_render_through_the_launcher_chooses_the_opengl_backend():
    """scripts/render.py sets MUJOCO_GL only if mujoco is not imported yet: through the launcher
    it is set as when render.py runs as a file."""
    expected = next((backend for backend, library in (("egl", "EGL"), ("osmesa", "OSMesa"))
                     if ctypes.util.find_library(library)), None)
    if expected is None:
        pytest.skip("no headless OpenGL library (libEGL or libOSMesa): nothing to choose")
    code = ("import os\nfrom scripts import console\ntry:\n    console.main(['render', '--help'])"
            "\nexcept SystemExit as e:\n    print(e.code, os.environ.get('MUJOCO_GL'))")
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    assert _python(code, env).splitlines()[-1] == f"0 {expected}"


def test_the_installed_command(tmp_path):
    command = shutil.which("sac-jax", path=sysconfig.get_path("scripts"))
    if command is None:
        pytest.skip("sac-jax is not installed in this environment (pip install -e .)")
    done = subprocess.run([command, "evaluate", str(tmp_path / "nowhere")], capture_output=True,
                          text=True, timeout=300, cwd=str(tmp_path))  # not the checkout
    assert done.returncode == 2
    assert done.stderr == f"error: {tmp_path / 'nowhere'}: no such run directory\n"


def test_every_package_directory_is_installed_and_no_top_level_scripts():
    tomllib = pytest.importorskip("tomllib")
    with open(os.path.join(ROOT, "pyproject.toml"), "rb") as f:
        setuptools = tomllib.load(f)["tool"]["setuptools"]
    package_dir = setuptools.get("package-dir", {})
    installed = {package_dir.get(name, name.replace(".", "/")) for name in setuptools["packages"]}
    on_disk = {os.path.relpath(path, ROOT) for top in ("sac_jax", "envs", "scripts")
               for path, _, files in os.walk(os.path.join(ROOT, top)) if "__init__.py" in files}
    assert installed == on_disk
    assert "scripts" not in setuptools["packages"] and package_dir["sac_jax_scripts"] == "scripts"
