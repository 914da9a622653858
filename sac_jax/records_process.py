"""A run's records written by a child Python process while it trains: TensorBoard's scalars
point by point, then curves.png at the end (`python -m sac_jax.records_process`).

Why a process: TensorBoard's writer and matplotlib take 0.2-0.3 and 0.3-0.5 s to import, and
imported on a thread of the training process they hold the GIL that the host loop needs between
chunks, while the device waits. In a child they load on a core of their own, and the training
process never imports them.
rejax's Pendulum-v1 SAC, 1 seed, warm, through scripts/train.py (alternated runs):
- on an H100 (2026-12-08, 3 rounds), matplotlib in a child: training 1.82-1.86 s against
  1.88-1.99 s with it imported on a thread (the jitted program: 1.63 s);
- on 2 cores of a 2.6 GHz Xeon (2026-12-08, two sets of 5 rounds against b723cb3, whose
  TensorBoard records were written on a thread of the training process): medians of training
  5.05 s against 5.22 s and of the process 6.36 s against 6.63 s with the child at the default
  priority; 4.90 s against 4.88 s and 6.17 s against 6.29 s with it niced (below).
The child runs at the lowest priority (`os.nice(19)`): on those 2 cores, `python -m
benchmarks.progress_overhead --repeats 7 --no-single-scan` (the `fast` preset, 1 seed) gave a
followed run +2.6 and +3.0 % over the bare chunks with a child of default priority, -0.2 and
+0.6 % with it niced, -0.1 and -0.5 % for b723cb3; BENCHMARKS.md's run (`--repeats 9`, niced)
+2.0 %. Single ratios spread over ±3 %; the child's 0.7 s of CPU costs about 1 % of that run.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
from typing import List, Optional, Sequence

import numpy as np

from sac_jax import plots
from sac_jax.metric_writers import Point, TensorBoard

CLOSED = b"closed\n"
"""The child's answer once TensorBoard's records are whole on disk."""


class RecordsProcess:
    """The run directory `run_dir`'s TensorBoard records (`metric_writers.TensorBoard`: the
    points of `history`, then those added) and its curves.png (`plots.write_curves`), written
    by a child process once `start`ed, as the run begins to train.

    `add_point` hands the child a point and returns at once; `close_tensorboard` waits until
    the records are whole; `write_curves` waits for the file; `close` ends a child not used.
    What the child could not write comes back from the next of these calls: an OSError as the
    system's (errno, words, filename), any other failure as RuntimeError with the child's last
    line. The child runs in a session of its own (the terminal's Ctrl-C, which stops a run
    after saving, does not reach it) and ends, its records whole, if its parent dies (its input
    closes). Where there is no child (never started, not startable, killed), this process
    writes: TensorBoard's records rebuilt from every point so far, then the rest."""

    def __init__(self, run_dir: str, history: Sequence[Point] = ()):
        self._run_dir = run_dir
        self._points: List[Point] = list(history)
        self._child: Optional[subprocess.Popen] = None
        self._here: Optional[TensorBoard] = None  # this process's writer, where no child writes
        self._failed = False  # the child reported a failure: nothing more is written

    def start(self) -> None:
        if self._child is not None or self._here is not None or self._failed:
            return
        try:
            self._child = subprocess.Popen(
                [sys.executable, "-m", "sac_jax.records_process"], stdin=subprocess.PIPE,
                stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)
        except OSError:  # no process to be had (memory, process limits): written here
            self._writer_here()
            return
        self._send("tensorboard", self._run_dir, self._points)

    def add_point(self, step: int, means, eval_returns) -> None:
        point = (int(step), dict(means), np.array(eval_returns))
        here = self._here
        self._points.append(point)
        if self._failed:
            return
        if self._child is not None:
            if self._send("point", *point) and self._child.poll() is None:
                return
            self._child_ended()  # written here from now on: every point so far rebuilt
        elif here is not None:
            here.add_point(*point)
        else:
            self._writer_here()  # every point so far, this one included

    def close_tensorboard(self) -> None:
        """Returns once TensorBoard's records hold every point, whole on disk."""
        if self._failed:
            return
        if self._child is not None:
            if self._send("close") and self._child.stdout.readline() == CLOSED:
                return
            self._child_ended()
        self._writer_here().close()

    def write_curves(self, *args, **kwargs) -> None:
        """`plots.write_curves(*args, **kwargs)`, in the child if there is one."""
        if self._child is None:
            return plots.write_curves(*args, **kwargs)
        self._send("curves", args, kwargs)
        _, err = self._child.communicate()
        if self._child.returncode < 0:  # killed by a signal (out of memory) before it drew
            return plots.write_curves(*args, **kwargs)
        if self._child.returncode:
            raise _child_error(err.decode(errors="replace"), "curves.png")

    def close(self) -> None:
        if self._child is not None and self._child.poll() is None:
            self._child.kill()
            self._child.communicate()

    def _send(self, *message) -> bool:
        """Hands the child `message`; False if it has ended (its return code says how)."""
        try:
            pickle.dump(message, self._child.stdin)
            self._child.stdin.flush()
            return True
        except BrokenPipeError:
            return False

    def _child_ended(self) -> None:
        """After the child ended unasked: raises the failure it reported; or, killed, leaves
        the writing to this process, TensorBoard's records rebuilt from every point so far."""
        _, err = self._child.communicate()
        code, self._child = self._child.returncode, None
        if code > 0:
            self._failed = True
            raise _child_error(err.decode(errors="replace"), "TensorBoard's records")
        self._writer_here()

    def _writer_here(self) -> TensorBoard:
        if self._here is None:
            self._here = TensorBoard(self._run_dir, self._points)
        return self._here


def _child_error(stderr: str, what: str) -> Exception:
    """The exception a child's last stderr line names: an OSError(errno, strerror, filename)
    it printed as `OSError errno|strerror|filename`, or RuntimeError naming `what`."""
    lines = [line for line in stderr.splitlines() if line.strip()]
    last = lines[-1] if lines else "the records process ended without a word"
    if last.startswith("OSError "):
        errno, strerror, filename = last[len("OSError "):].split("|", 2)
        return OSError(int(errno), strerror, filename or None)
    return RuntimeError(f"{what}: {last}")


def _serve() -> None:
    """The child's side of `RecordsProcess`: writes TensorBoard's records as the points come,
    answers `CLOSED` once they are whole, draws curves.png and ends at once (its parent waits
    for that). A closed input (the parent gone) closes the records and ends it."""
    os.nice(19)  # never urgent while the run trains: its threads go first on a busy CPU
    tensorboard: Optional[TensorBoard] = None
    try:
        try:
            while True:
                kind, *args = pickle.load(sys.stdin.buffer)
                if kind == "tensorboard":
                    tensorboard = TensorBoard(*args)  # TensorBoard's writer loads on its thread
                    plots.prepare()  # and matplotlib on this one
                elif kind == "point":
                    tensorboard.add_point(*args)
                elif kind == "close":
                    tensorboard, closing = None, tensorboard
                    closing.close()
                    sys.stdout.buffer.write(CLOSED)
                    sys.stdout.buffer.flush()
                else:
                    plots.write_curves(*args[0], **args[1])
                    os._exit(0)  # the file is whole; the interpreter's cleanup took 0.3 s here
        except EOFError:
            if tensorboard is not None:
                tensorboard.close()
    except OSError as error:
        if error.errno is None:
            raise
        print(f"OSError {error.errno}|{error.strerror}|{error.filename or ''}", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    _serve()
