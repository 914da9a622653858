"""Render an episode of a saved policy to a GIF or an MP4.

    python scripts/render.py runs/fast                            # RUN_DIR/episode.gif
    python scripts/render.py runs/pendulum --out swing.gif --steps 100
    python scripts/render.py runs/fast --out pole.mp4 --width 640 --height 480   # imageio-ffmpeg
    MUJOCO_GL=osmesa python scripts/render.py runs/fast           # software GL, no EGL

Runs one episode of the deterministic policy of one of the run's seeds in our environment (a
jitted `lax.scan` of `--steps` steps from the reset drawn with `--episode-seed`, cut where the
episode ends) and draws the initial state and the state after each step, in real time by
default (fps = 1 / dt):
    MuJoCo environments  `mujoco.Renderer`, headless, on the MJCF model our environment
                         simulates, posed with the qpos of our MJX states; the OpenGL backend
                         is MUJOCO_GL: egl if libEGL is found (system package libegl1), else
                         osmesa if libOSMesa is (libosmesa6), unless MUJOCO_GL is already set
    Pendulum-v1          matplotlib (the pendulum rod, θ = 0 upright)

The file is written under a temporary name in the same directory and renamed; an existing file
is kept unless `--force`. Bad input (run directory, checkpoint, seed, values, an existing
output, an output whose directory is missing or not writable, checked before anything is
compiled and again at the write) ends with one line on stderr and exit 2, leaving no file
behind; a missing library or OpenGL backend with one line and exit 1.
"""

from __future__ import annotations

import ctypes.util
import dataclasses
import importlib
import os
import sys
import warnings
from typing import Literal, Optional

GL_HELP = ("set MUJOCO_GL=egl (system package libegl1) or MUJOCO_GL=osmesa (libosmesa6) for "
           "headless rendering")


def _default_gl_backend() -> None:
    """Sets MUJOCO_GL for headless rendering (egl, else osmesa, whichever library is found)
    unless it is set; must run before mujoco is imported, which reads it once."""
    if "MUJOCO_GL" in os.environ or "mujoco" in sys.modules:
        return
    for backend, library in (("egl", "EGL"), ("osmesa", "OSMesa")):
        if ctypes.util.find_library(library):
            os.environ["MUJOCO_GL"] = backend
            return


def _import_mujoco() -> None:
    """Imports mujoco, which loads the MUJOCO_GL backend as it is imported: a backend whose
    library is missing fails there (e.g. osmesa without libOSMesa), ending with one line."""
    try:
        import mujoco  # noqa: F401
    except Exception as error:  # ImportError, AttributeError, RuntimeError, ... by backend
        reason = str(error).strip().splitlines()[0] if str(error).strip() else ""
        sys.exit(f"error: MUJOCO_GL={os.environ.get('MUJOCO_GL', '')!r}: importing mujoco "
                 f"failed ({type(error).__name__}: {reason}); {GL_HELP}")


_default_gl_backend()
_import_mujoco()

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import tyro  # noqa: E402

import envs  # noqa: E402
import sac_jax  # noqa: E402
from envs.mjx_env import MjxEnv  # noqa: E402
from envs.pendulum import PendulumData  # noqa: E402
from envs.task_adapter import TaskAdapter  # noqa: E402
from sac_jax import plots, run_dir  # noqa: E402
from sac_jax.messages import first_line  # noqa: E402
from sac_jax.cli import (MissingDependency, fail, parse, positive, prng_seed,  # noqa: E402
                         run_main)

FORMATS = (".gif", ".mp4")


@dataclasses.dataclass(frozen=True)
class RenderArgs:
    """Render an episode of a saved policy to a GIF or MP4."""

    run: tyro.conf.Positional[str]
    """Run directory written by scripts/train.py."""
    out: Optional[str] = None
    """Output file, .gif or .mp4 (default RUN/episode.gif)."""
    force: bool = False
    """Replace an existing --out file."""
    steps: Optional[int] = None
    """Most environment steps to draw (default: a whole episode)."""
    fps: Optional[int] = None
    """Frames per second (default 1 / dt of the environment: real time)."""
    width: int = 480
    """Image width in pixels."""
    height: int = 320
    """Image height in pixels."""
    seed: int = 0
    """Which of the run's seeds to render, 0..seeds-1."""
    episode_seed: int = 0
    """PRNG seed of the episode's initial state."""
    policy: Literal["best", "last"] = "best"
    """Which actor of the seed: "best", the delivered one (`sac_jax.selection`), or
    "last", the last update's."""

    def __post_init__(self):
        for name in ("steps", "fps", "width", "height"):
            if getattr(self, name) is not None:
                positive(name, getattr(self, name))
        prng_seed("episode_seed", self.episode_seed)


def rollout(policy: sac_jax.SavedPolicy, env, key: jax.Array, steps: int):
    """One episode of at most `steps` steps from `env.reset(key)`, in one jitted scan.

    Returns (poses, total return, steps taken): poses (steps taken + 1, ...) are the initial
    state's and each step's positions, qpos (nq,) for MJX and θ () for Pendulum.
    """
    def pose(data):
        if isinstance(data, PendulumData):
            return data.theta
        # an adapted task's state (Playground's, Brax's) holds its MJX data
        return (env.physics(data) if isinstance(env, TaskAdapter) else data).qpos

    @jax.jit  # the parameters are an argument, not constants: the compilation cache keeps it
    def run(actor_params, key):
        def step(state, _):
            state = env.step(state, policy.agent.act(actor_params, state.obs))
            return state, (pose(state.data), state.reward, state.terminated | state.truncated)

        first = env.reset(key)
        _, (poses, rewards, done) = jax.lax.scan(step, first, None, length=steps)
        return jnp.concatenate([pose(first.data)[None], poses]), rewards, done

    poses, rewards, done = jax.device_get(run(policy.actor_params, key))
    length = int(np.argmax(done)) + 1 if done.any() else steps
    return poses[:length + 1], float(rewards[:length].sum()), length


def _side_camera(model, data, aspect: float):
    """A free camera looking along +y at the x-z plane the pendulums move in, framing the
    bounding box of the model's geoms in `data`'s pose (planes such as floors left out) with
    a 15% margin, for images of width / height = `aspect`."""
    import mujoco

    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    points = []
    for g in range(model.ngeom):
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE:
            continue
        center, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        rotation = data.geom_xmat[g].reshape(3, 3)
        points.append(data.geom_xpos[g] + (center + corners * half) @ rotation.T)
    points = np.concatenate(points)
    low, high = points.min(axis=0), points.max(axis=0)
    half_width, half_depth, half_height = (high - low) / 2
    tan_half_fovy = np.tan(np.radians(model.vis.global_.fovy) / 2)
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.lookat[:] = (low + high) / 2
    camera.distance = 1.15 * max(half_height, half_width / aspect) / tan_half_fovy + half_depth
    camera.azimuth, camera.elevation = 90.0, 0.0
    return camera


def mujoco_renderer(env: MjxEnv, width: int, height: int):
    """`mujoco.Renderer` of width x height pixels on a copy of the environment's model, lit by
    a brighter headlight (the models have no lights of their own). Raises MissingDependency,
    one line, if no OpenGL context can be made."""
    import mujoco

    model = env.mj_model.__copy__()
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    model.vis.headlight.ambient, model.vis.headlight.diffuse = [0.5] * 3, [0.7] * 3
    try:
        with warnings.catch_warnings():  # glfw warns before failing without a display
            warnings.simplefilter("ignore")
            return mujoco.Renderer(model, height, width)
    except Exception as error:  # each backend fails its own way (FatalError, ImportError, ...)
        raise MissingDependency(f"no OpenGL context for MuJoCo's renderer (MUJOCO_GL="
                                f"{os.environ.get('MUJOCO_GL', '')!r}: {first_line(error)}); "
                                f"{GL_HELP}") from None


def mujoco_frames(renderer, poses: np.ndarray) -> np.ndarray:
    """(T, height, width, 3) uint8 images by `renderer` (`mujoco_renderer`) of its model at
    qpos `poses` (T, nq), seen from the side (`_side_camera` of the first pose)."""
    import mujoco

    model = renderer.model
    data = mujoco.MjData(model)
    frames, camera = [], None
    for qpos in poses:
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        if camera is None:
            camera = _side_camera(model, data, renderer.width / renderer.height)
        renderer.update_scene(data, camera)
        frames.append(renderer.render())
    return np.stack(frames)


def pendulum_frames(thetas: np.ndarray, width: int, height: int, dt: float) -> np.ndarray:
    """(T, height, width, 3) uint8 matplotlib drawings of the pendulum at angles `thetas`
    (T,): the rod from the pivot to (-sin θ, cos θ), θ = 0 upright, as Gymnasium draws it."""
    dpi = 100
    figure = plots.figure(figsize=(width / dpi, height / dpi), dpi=dpi)
    canvas = figure.canvas
    axes = figure.add_axes((0, 0, 1, 1))
    axes.set(xlim=(-1.3, 1.3), ylim=(-1.3, 1.3), aspect="equal")
    axes.axis("off")
    rod, = axes.plot([], [], color="tab:red", linewidth=8, solid_capstyle="round")
    axes.plot([0], [0], "o", color="black", markersize=6)
    clock = axes.text(0.02, 0.97, "", transform=axes.transAxes, va="top")
    frames = []
    for t, theta in enumerate(thetas):
        rod.set_data([0.0, -np.sin(theta)], [0.0, np.cos(theta)])
        clock.set_text(f"t = {t * dt:.2f} s")
        canvas.draw()
        frames.append(np.asarray(canvas.buffer_rgba())[..., :3].copy())
    return np.stack(frames)


def _importable(module: str) -> bool:
    try:
        importlib.import_module(module)
        return True
    except ImportError:
        return False


def _video_writer_missing(extension: str) -> bool:
    """Whether `extension` needs a video encoder (imageio-ffmpeg or PyAV) that is not installed."""
    return extension == ".mp4" and not any(map(_importable, ("imageio_ffmpeg", "av")))


def write_video(path: str, frames: np.ndarray, fps: int, replace: bool = False) -> None:
    """Writes frames (T, H, W, 3) uint8 to `path` (.gif looping, or .mp4), encoded in memory
    and written by `run_dir.write_file`: whole or absent, no temporary file left on an OSError
    (raised as is); an existing `path` is replaced only with `replace` (else FileExistsError,
    and it is left as it was)."""
    import imageio.v3 as iio

    extension = os.path.splitext(path)[1].lower()
    options = ({"duration": 1000.0 / fps, "loop": 0} if extension == ".gif" else {"fps": fps})
    data = iio.imwrite("<bytes>", frames, extension=extension, **options)
    run_dir.write_file(path, data, replace=replace)


def _unwritable(out: str) -> Optional[str]:
    """Why a file cannot be created at `out` (its directory is missing, not a directory, or
    not writable to this process), or None."""
    directory = os.path.dirname(os.path.abspath(out))
    if not os.path.exists(directory):
        return f"no such directory {directory}"
    if not os.path.isdir(directory):
        return f"{directory} is not a directory"
    if not os.access(directory, os.W_OK | os.X_OK):
        return f"directory {directory} is not writable (permission denied)"
    return None


def _check_output(out: str, force: bool) -> None:
    """ValueError for an output this script must not write; MissingDependency for .mp4
    without a video encoder."""
    extension = os.path.splitext(out)[1].lower()
    if extension not in FORMATS:
        raise ValueError(f"--out={out}: unknown format {extension or '(none)'}; use "
                         f"{' or '.join(FORMATS)}")
    if os.path.exists(out) and not force:
        raise ValueError(f"--out={out}: already exists; use --force to replace it")
    if os.path.isdir(out):
        raise ValueError(f"--out={out}: is a directory")
    reason = _unwritable(out)
    if reason:
        raise ValueError(f"--out={out}: cannot be written: {reason}")
    if _video_writer_missing(extension):
        raise MissingDependency(f"--out={out}: writing MP4 needs imageio-ffmpeg (pip install "
                                "imageio-ffmpeg) or PyAV; or write a .gif")


def main(argv=None) -> int:
    try:
        args = parse(RenderArgs, argv, description=__doc__)
        run_dir.read_config(args.run)
        out = args.out or os.path.join(args.run, "episode.gif")
        _check_output(out, args.force)
        sac_jax.enable_compilation_cache()
        policy = sac_jax.load_policy(args.run, args.seed, args.policy)
    except ValueError as error:  # also UsageError, RunDirError and CheckpointError
        return fail(error, 2)
    except MissingDependency as error:
        return fail(error, 1)
    env = policy.config.make_env()
    steps = args.steps or env.max_episode_steps
    fps = args.fps or max(1, round(1.0 / env.dt))
    try:
        # The OpenGL context first: no compiling before knowing that it can be drawn.
        renderer = (mujoco_renderer(env, args.width, args.height)
                    if envs.spec(env.name).renderer == "mujoco"
                    else None)
    except MissingDependency as error:
        return fail(error, 1)
    poses, total, length = rollout(policy, env, jax.random.key(args.episode_seed), steps)
    if renderer is None:
        frames = pendulum_frames(poses, args.width, args.height, env.dt)
    else:
        with renderer:
            frames = mujoco_frames(renderer, poses)
    try:
        write_video(out, frames, fps, replace=args.force)
    except FileExistsError:
        print(f"error: --out={out}: appeared while rendering; kept it (use --force to replace "
              "it)", file=sys.stderr)
        return 2
    except OSError as error:  # e.g. the directory went away or became read-only meanwhile
        reason = _unwritable(out) or error.strerror or type(error).__name__
        return fail(ValueError(f"--out={out}: cannot be written: {reason}"), 2)
    print(f"wrote {out}: {len(frames)} frames of {args.width}x{args.height} at {fps} fps, "
          f"{length} steps of {policy.config.env} (seed {args.seed}), return {total:.1f}")
    return 0


if __name__ == "__main__":
    run_main(main)
