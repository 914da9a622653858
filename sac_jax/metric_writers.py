"""A run's figures as files: metrics.csv and summary.json at the end, TensorBoard scalars live."""

from __future__ import annotations

import csv
import io
import os
import sys
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


def _summary_writer_class():
    """tensorboardX's `SummaryWriter`, imported without importing torch. tensorboardX's writer
    module imports torch when it is installed, only to accept torch tensors, which scalars do
    not need: 2.2 s of every run on the CPU and 3-5 s on a GPU host with torch. A torch the
    process has already imported is used as it is."""
    if "torch" in sys.modules or "tensorboardX" in sys.modules:
        from tensorboardX import SummaryWriter
        return SummaryWriter
    sys.modules["torch"] = None  # `import torch` raises ImportError while this is set
    try:
        from tensorboardX import SummaryWriter
    finally:
        del sys.modules["torch"]
    return SummaryWriter


class TensorBoard(BackgroundWrites):
    """Scalars of each evaluation point: every metric's mean over seeds under `mean/`, and each
    seed's evaluation return under `eval_return/seed_<i>`, written on the background thread
    (one scalar per seed: 28 ms a point for 256 seeds on the H100's host, which the device
    would otherwise wait for)."""

    def __init__(self, run_dir: str):
        super().__init__()
        self._writer = _summary_writer_class()(os.path.join(run_dir, "tensorboard"))

    def _write(self, step: int, means: Dict[str, float], eval_returns: np.ndarray) -> None:
        for name, value in means.items():
            if name != "env_steps" and np.isfinite(value):
                self._writer.add_scalar(f"mean/{name}", value, step)
        for s, value in enumerate(eval_returns):
            self._writer.add_scalar(f"eval_return/seed_{s}", float(value), step)
        self._writer.flush()

    def add_point(self, step: int, means: Dict[str, float], eval_returns) -> None:
        self.submit(self._write, step, dict(means), np.array(eval_returns))

    def close(self) -> None:
        try:
            super().close()
        finally:
            self._writer.close()
