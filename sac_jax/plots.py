"""Figures of a run directory, drawn with matplotlib's Agg backend (no display needed)."""

from __future__ import annotations

import io
import os
import pickle
import subprocess
import sys
from typing import Dict

import numpy as np

from sac_jax import background
from sac_jax.whole_file import write_file


def figure(**kwargs):
    """A matplotlib Figure drawn by the Agg canvas, made without pyplot: no global figure state
    (safe from any thread), and an import of 0.30-0.43 s against pyplot's 0.45-0.49 (2 CPU
    cores of an AMD EPYC, 3 alternated processes each)."""
    Figure, FigureCanvasAgg = _figure_classes()
    fig = Figure(**kwargs)
    FigureCanvasAgg(fig)
    return fig


def prepare() -> None:
    """Imports what `figure` needs, for `write_curves`; a `CurvesProcess` does it as it starts.
    A failure is left for `write_curves` to meet and report."""
    try:
        _figure_classes()
    except Exception:  # noqa: BLE001
        pass


def _figure_classes():
    """matplotlib's Figure and Agg canvas classes, imported holding
    `background.SYNTAX_TREE_IMPORTS` (matplotlib parses its rc values as it loads)."""
    with background.SYNTAX_TREE_IMPORTS:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    return Figure, FigureCanvasAgg


def write_curves(run_dir: str, metrics: Dict[str, np.ndarray], points: int, title: str,
                 threshold=None) -> None:
    """curves.png: mean evaluation return of the last actor over seeds against environment
    steps, with the min-max band over seeds, the mean confirmed return of the delivered actor,
    and the task's solving threshold."""
    steps = metrics["env_steps"][0, :points]
    returns = metrics["eval_return"][:, :points]
    fig = figure(figsize=(6, 4), dpi=100)
    ax = fig.subplots()
    ax.fill_between(steps, returns.min(axis=0), returns.max(axis=0), alpha=0.3,
                    label=f"min-max over {returns.shape[0]} seed(s)")
    ax.plot(steps, returns.mean(axis=0), marker="o", label="mean, last actor")
    ax.plot(steps, metrics["delivered_return"][:, :points].mean(axis=0), marker=".",
            linestyle=":", label="mean, delivered actor")
    if threshold is not None:
        ax.axhline(threshold, color="grey", linestyle="--", label=f"solved ({threshold:g})")
    ax.set(xlabel="environment steps", ylabel="evaluation return", title=title)
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0))
    ax.grid(alpha=0.3)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", bbox_inches="tight")
    write_file(os.path.join(run_dir, "curves.png"), buffer.getvalue())


class CurvesProcess:
    """`write_curves` in a child Python process (`python -m sac_jax.plots`), `start`ed as a run
    begins to train: matplotlib is imported there, on a core of its own, while the run trains,
    not on a thread of the training process, where the host loop's work between chunks would
    wait for it (the GIL). `write_curves` hands the child its arguments and waits for the file;
    `close` ends a child not used. The child ignores the terminal's Ctrl-C (a session of its
    own) and ends without drawing if its parent dies (its input closes). Where there is no
    child to draw (never started, not startable, killed), this process draws.

    rejax's Pendulum-v1 SAC, 1 seed, warm, on an H100 (2026-12-08, 3 alternated runs of
    scripts/train.py): training took 1.82-1.86 s against 1.88-1.99 s with matplotlib imported on
    a thread of the run (the jitted program: 1.63 s). On 2 CPU cores, no change beyond noise."""

    def __init__(self):
        self._child = None

    def start(self) -> None:
        if self._child is None:
            try:
                self._child = subprocess.Popen(  # JAX, imported with sac_jax, kept off the GPU
                    [sys.executable, "-m", "sac_jax.plots"], stdin=subprocess.PIPE,
                    stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True,
                    env=dict(os.environ, JAX_PLATFORMS="cpu"))
            except OSError:  # no process to be had (memory, process limits): drawn here
                pass

    def write_curves(self, *args, **kwargs) -> None:
        """`write_curves(*args, **kwargs)`, in the child if there is one. Raises OSError for a
        file the child could not write, RuntimeError with its last line for any other failure
        it reports."""
        if self._child is None:
            return write_curves(*args, **kwargs)
        try:
            pickle.dump((args, kwargs), self._child.stdin)
        except BrokenPipeError:
            pass  # the child has ended: its return code says how
        _, err = self._child.communicate()
        if self._child.returncode < 0:  # killed by a signal (out of memory) before it drew
            return write_curves(*args, **kwargs)
        if self._child.returncode:
            raise _child_error(err.decode(errors="replace"))

    def close(self) -> None:
        if self._child is not None and self._child.poll() is None:
            self._child.kill()
            self._child.communicate()


def _child_error(stderr: str) -> Exception:
    """The exception a child's last stderr line names: an OSError(errno, strerror, filename)
    it printed as `OSError errno|strerror|filename`, or RuntimeError."""
    lines = [line for line in stderr.splitlines() if line.strip()]
    last = lines[-1] if lines else "the figure process ended without a word"
    if last.startswith("OSError "):
        errno, strerror, filename = last[len("OSError "):].split("|", 2)
        return OSError(int(errno), strerror, filename or None)
    return RuntimeError(f"curves.png: {last}")


def _serve() -> None:
    """The child's side of `CurvesProcess`: imports matplotlib, then draws what its parent
    sends and ends at once (its parent waits for that); a closed input (the parent gone) ends
    it without drawing."""
    prepare()
    try:
        args, kwargs = pickle.load(sys.stdin.buffer)
    except EOFError:
        return
    try:
        write_curves(*args, **kwargs)
    except OSError as error:
        if error.errno is None:
            raise
        print(f"OSError {error.errno}|{error.strerror}|{error.filename or ''}", file=sys.stderr)
        sys.exit(1)
    os._exit(0)  # the file is whole; an interpreter's cleanup of jax's modules took 0.3 s here


if __name__ == "__main__":
    _serve()
