"""Figures of a run directory, drawn with matplotlib's Agg backend (no display needed)."""

from __future__ import annotations

import io
import os
from typing import Dict

import numpy as np

from sac_jax.run_dir import write_file


def prepare() -> None:
    """Imports matplotlib and its Agg backend, which `write_curves` needs (0.4-0.6 s on 2 CPU
    cores, a third of what a warm `fast` run spends outside training); `sac_jax.cli` does it
    on a thread of its own once the run trains, while the host only waits for the device. A
    failure is left for `write_curves` to meet and report."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot  # noqa: F401
    except Exception:  # noqa: BLE001
        pass


def write_curves(run_dir: str, metrics: Dict[str, np.ndarray], points: int, title: str,
                 threshold=None) -> None:
    """curves.png: mean evaluation return of the last actor over seeds against environment
    steps, with the min-max band over seeds, the mean confirmed return of the delivered actor,
    and the task's solving threshold."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    steps = metrics["env_steps"][0, :points]
    returns = metrics["eval_return"][:, :points]
    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
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
    plt.close(fig)
    write_file(os.path.join(run_dir, "curves.png"), buffer.getvalue())


