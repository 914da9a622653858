"""Running a configuration from the host: compile once, train all seeds in one program, follow
progress, time it, and write a run directory."""

from __future__ import annotations

import csv
import dataclasses
import json
import os
import shutil
import tempfile
import time
from typing import Callable, Dict, Optional

import jax
import numpy as np

from sac_jax.config import SACConfig
from sac_jax.parallel import seeds_program
from sac_jax.presets import SOLVED_RETURN
from sac_jax.train import make_train_parts


@dataclasses.dataclass
class RunResult:
    """`metrics`: numpy arrays (seeds, num_evals); `summary`: plain JSON-able figures."""

    state: object
    metrics: Dict[str, np.ndarray]
    summary: dict


def _nanmean(values) -> float:
    """Mean of the finite values, NaN if there are none (without numpy's warning)."""
    finite = [v for v in values if np.isfinite(v)]
    return float(np.mean(finite)) if finite else float("nan")


def solved_at(eval_returns: np.ndarray, env_steps: np.ndarray, threshold: float) -> Optional[int]:
    """First environment step whose evaluation return reaches `threshold`, or None."""
    hits = np.nonzero(eval_returns >= threshold)[0]
    return int(env_steps[hits[0]]) if hits.size else None


def run_training(config: SACConfig, seeds: int = 1, seed: int = 0,
                 on_point: Optional[Callable[[int, dict, float], None]] = None) -> RunResult:
    """Trains `seeds` seeds (keys split from `seed`) vmapped in one program, split over the local
    devices when there are several and they divide `seeds` (`sac_jax.parallel.seeds_program`),
    driven from the host one chunk at a time (`sac_jax.train.make_train_parts`): the compiled
    chunk holds no host callback, so JAX's persistent compilation cache keeps it, and progress
    is read between chunks.

    `on_point(env_steps, mean_metrics, elapsed_s)` is called at every evaluation point with the
    metrics averaged over seeds. The summary holds compile and run seconds, final evaluation
    returns, the first solving step per seed, and the training wall time (compile excluded) at
    which the mean over seeds first reached the task's threshold.
    """
    threshold = SOLVED_RETURN.get(config.env)
    parts = make_train_parts(config)
    init = seeds_program(parts.init, seeds)
    chunk = seeds_program(parts.chunk, seeds, donate=True)
    keys = jax.random.split(jax.random.key(seed), seeds)
    t0 = time.perf_counter()
    runner = init(keys)
    chunk = chunk.lower(runner).compile()
    compile_s = time.perf_counter() - t0
    start = time.perf_counter()
    walls: Dict[int, float] = {}
    evals_done = 0
    for _ in range(parts.num_chunks):
        runner = chunk(runner)
        iterations = int(runner.iteration[0])  # waits for the chunk
        evals = max(0, (iterations - config.prefill_iterations) // config.iterations_per_eval)
        if evals > evals_done:
            evals_done = evals
            point = jax.device_get({k: v[:, evals - 1] for k, v in runner.outputs.items()})
            step = int(point["env_steps"][0])
            walls[step] = time.perf_counter() - start
            if on_point is not None:
                on_point(step, {k: _nanmean(v) for k, v in point.items()}, walls[step])
    run_s = time.perf_counter() - start
    metrics = {k: np.asarray(v) for k, v in jax.device_get(runner.outputs).items()}
    steps = metrics["env_steps"][0]
    mean_eval = metrics["eval_return"].mean(axis=0)
    solved_mean = solved_at(mean_eval, steps, threshold) if threshold is not None else None
    summary = {
        "env": config.env,
        "seeds": seeds,
        "total_steps": int(steps[-1]),
        "eval_return": [float(r) for r in metrics["eval_return"][:, -1]],
        "solved_threshold": threshold,
        "solved_at_step": [solved_at(r, steps, threshold) if threshold is not None else None
                           for r in metrics["eval_return"]],
        "solved_wall_s": round(walls[solved_mean], 3) if solved_mean is not None else None,
        "compile_s": round(compile_s, 3),
        "run_s": round(run_s, 3),
        "wall_s": round(compile_s + run_s, 3),
    }
    return RunResult(state=runner, metrics=metrics, summary=summary)


def write_run_dir(out: str, config: SACConfig, preset: str, result: RunResult) -> None:
    """Writes config.json, metrics.csv and summary.json into a new directory `out`, built under
    a temporary name and renamed at the end, so `out` is either complete or absent."""
    parent = os.path.dirname(os.path.abspath(out))
    os.makedirs(parent, exist_ok=True)
    tmp = tempfile.mkdtemp(prefix=".tmp-run-", dir=parent)
    try:
        with open(os.path.join(tmp, "config.json"), "w") as f:
            json.dump(dataclasses.asdict(config), f, indent=2)
        names = ["env_steps", "eval_return", "train_return"] + sorted(
            k for k in result.metrics if k not in ("env_steps", "eval_return", "train_return"))
        with open(os.path.join(tmp, "metrics.csv"), "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(["seed"] + names)
            seeds, points = result.metrics["eval_return"].shape
            for s in range(seeds):
                for p in range(points):
                    writer.writerow([s] + [result.metrics[k][s, p].item() for k in names])
        with open(os.path.join(tmp, "summary.json"), "w") as f:
            json.dump(dict(result.summary, preset=preset), f, indent=2)
        os.rename(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
