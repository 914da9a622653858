"""Figures of a run directory, drawn with matplotlib's Agg backend (no display needed)."""

from __future__ import annotations

import io
import os
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
    """Imports what `figure` needs, for `write_curves`; the records process
    (`sac_jax.records_process`) does it as it starts. A failure is left for `write_curves` to
    meet and report."""
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
