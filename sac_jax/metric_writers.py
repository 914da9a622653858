"""A run's figures as files: metrics.csv and summary.json at the end, TensorBoard scalars live."""

from __future__ import annotations

import csv
import glob
import io
import os
import shutil
import time
from typing import Dict, List, Sequence, Tuple

import numpy as np

from sac_jax.background import BackgroundWrites
from sac_jax.whole_file import write_file, write_json

Point = Tuple[int, Dict[str, float], np.ndarray]
"""One evaluation point as `sac_jax.run.run_training` reports it: (environment steps, means
over seeds, each seed's evaluation return)."""


def write_metrics(run_dir: str, metrics: Dict[str, np.ndarray], points: int) -> None:
    """metrics.csv: one row per evaluation point (the first `points`) and seed."""
    first = ["env_steps", "eval_return", "train_return"]
    names = first + sorted(k for k in metrics if k not in first)
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(["seed"] + names)
    for s in range(metrics["eval_return"].shape[0]):
        for p in range(points):
            writer.writerow([s] + [metrics[k][s, p].item() for k in names])
    write_file(os.path.join(run_dir, "metrics.csv"), text.getvalue().encode())


def write_summary(run_dir: str, summary: dict) -> None:
    write_json(os.path.join(run_dir, "summary.json"), summary)


class TensorBoard(BackgroundWrites):
    """Scalars of each evaluation point: every metric's mean over seeds under `mean/`, and each
    seed's evaluation return under `eval_return/seed_<i>`, one event per point, written on the
    background thread (one scalar per seed: 28 ms a point for 256 seeds on the H100's host with
    tensorboardX, which the device would otherwise wait for). The writer is the `tensorboard`
    package's own event file writer, which imports neither TensorFlow nor torch
    (tensorboardX's imports torch where it is installed: 2.2 s of every run on the CPU).

    The run directory's `tensorboard/` holds exactly the points of `history` (those of the state
    the run starts from: `sac_jax.run.evaluation_points`) and then those added. A run killed
    after writing point k but before saving the checkpoint holding it computes point k again
    when resumed; so at the start the directory is rebuilt from `history`, under a temporary
    name swapped in for the old one (`rebuild`), and each point is in it exactly once however
    often the run was killed and resumed."""

    def __init__(self, run_dir: str, history: Sequence[Point] = ()):
        super().__init__()
        self._writer = None
        self.submit(self._open, os.path.join(run_dir, "tensorboard"), list(history))

    def _open(self, directory: str, history: List[Point]) -> None:
        from tensorboard.summary.writer.event_file_writer import EventFileWriter

        rebuild(directory, history)
        self._writer = EventFileWriter(directory)

    def _write(self, step: int, means: Dict[str, float], eval_returns: np.ndarray) -> None:
        self._writer.add_event(point_event(step, means, eval_returns, time.time()))
        self._writer.flush()

    def add_point(self, step: int, means: Dict[str, float], eval_returns) -> None:
        self.submit(self._write, step, dict(means), np.array(eval_returns))

    def close(self) -> None:
        try:
            super().close()
        finally:
            if self._writer is not None:
                self._writer.close()


def rebuild(directory: str, history: Sequence[Point]) -> None:
    """Makes `directory` an event directory holding exactly the points of `history`, and
    nothing that was in it before: written complete under a temporary name, then renamed in
    place of the old one (itself renamed aside first, and removed). A kill between the two
    renames leaves no `directory` (and the old one aside): the next rebuild clears what such
    a kill left, and writes it again."""
    from tensorboard.summary.writer.event_file_writer import EventFileWriter

    if not history and not os.path.exists(directory):
        return  # a new run: nothing to write or replace
    parent, name = os.path.split(os.path.abspath(directory))
    for left in glob.glob(os.path.join(parent, f".{glob.escape(name)}.*-*")):
        shutil.rmtree(left, ignore_errors=True)  # a killed rebuild's, or this one's last try
    new, old = (os.path.join(parent, f".{name}.{what}-{os.getpid()}") for what in ("new", "old"))
    writer = EventFileWriter(new)
    try:
        for step, means, eval_returns in history:
            writer.add_event(point_event(step, means, eval_returns, time.time()))
    finally:
        writer.close()
    if os.path.exists(directory):
        os.rename(directory, old)
    os.rename(new, directory)
    shutil.rmtree(old, ignore_errors=True)


def point_scalars(means: Dict[str, float], eval_returns: np.ndarray) -> Dict[str, float]:
    """The scalars of one evaluation point, by tag: `mean/<name>` for every finite mean but
    the step itself, and `eval_return/seed_<i>` for each seed (TensorBoard's and W&B's)."""
    scalars = {f"mean/{name}": float(value) for name, value in means.items()
               if name != "env_steps" and np.isfinite(value)}
    scalars.update({f"eval_return/seed_{s}": float(value) for s, value in enumerate(eval_returns)})
    return scalars


def point_event(step: int, means: Dict[str, float], eval_returns: np.ndarray,
                wall_time: float):
    """The TensorBoard `Event` of one evaluation point: its `point_scalars`."""
    from tensorboard.compat.proto.event_pb2 import Event
    from tensorboard.compat.proto.summary_pb2 import Summary

    values = [Summary.Value(tag=tag, simple_value=value)
              for tag, value in point_scalars(means, eval_returns).items()]
    return Event(wall_time=wall_time, step=step, summary=Summary(value=values))
