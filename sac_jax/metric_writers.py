"""A run's figures as files: metrics.csv and summary.json at the end, TensorBoard scalars live."""

from __future__ import annotations

import csv
import io
import os
import time
from typing import Dict

import numpy as np

from sac_jax.background import BackgroundWrites
from sac_jax.run_dir import write_file, write_json


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
    background thread (one scalar per seed: 28 ms a point for 256 seeds on the H100's host,
    which the device would otherwise wait for). The writer is the `tensorboard` package's own
    event file writer, which imports neither TensorFlow nor torch (tensorboardX's imports
    torch where it is installed: 2.2 s of every run on the CPU)."""

    def __init__(self, run_dir: str):
        super().__init__()
        from tensorboard.summary.writer.event_file_writer import EventFileWriter

        self._writer = EventFileWriter(os.path.join(run_dir, "tensorboard"))

    def _write(self, step: int, means: Dict[str, float], eval_returns: np.ndarray) -> None:
        self._writer.add_event(point_event(step, means, eval_returns, time.time()))
        self._writer.flush()

    def add_point(self, step: int, means: Dict[str, float], eval_returns) -> None:
        self.submit(self._write, step, dict(means), np.array(eval_returns))

    def close(self) -> None:
        try:
            super().close()
        finally:
            self._writer.close()


def point_event(step: int, means: Dict[str, float], eval_returns: np.ndarray,
                wall_time: float):
    """The TensorBoard `Event` of one evaluation point: a scalar `mean/<name>` for every finite
    mean but the step itself, and `eval_return/seed_<i>` for each seed."""
    from tensorboard.compat.proto.event_pb2 import Event
    from tensorboard.compat.proto.summary_pb2 import Summary

    values = [Summary.Value(tag=f"mean/{name}", simple_value=value)
              for name, value in means.items() if name != "env_steps" and np.isfinite(value)]
    values += [Summary.Value(tag=f"eval_return/seed_{s}", simple_value=float(value))
               for s, value in enumerate(eval_returns)]
    return Event(wall_time=wall_time, step=step, summary=Summary(value=values))
