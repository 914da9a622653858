"""Optional Weights & Biases tracking of a run, as CleanRL's `--track`: the scalars TensorBoard
gets at each evaluation point (`metric_writers.point_scalars`), logged with `step=env_steps`;
the run's configuration as the W&B run's config; summary.json's figures as its summary.

`wandb` is an optional extra (`pip install -e ".[track]"`): `check_available` says in one line
what to install. The W&B run's id, project, entity, name and mode are kept in the run
directory's wandb.json, written before the W&B run starts, so `--resume` continues the same
W&B run. W&B's own files go under the run directory (or $WANDB_DIR where set).

Each point is logged exactly once however often the run is killed and resumed: a resumed run
asks W&B which step its next log would be (online, W&B knows the steps it holds; offline,
each process writes a local log of its own, so the earlier logs of the run are read back,
`sac_jax.wandb_records`) and logs, first from the checkpoint's points and then live, only the
points after the last one held. Steps are increasing, so the points held are always the first
ones.
"""

from __future__ import annotations

import importlib.util
import json
import os
import secrets
import string
from typing import Dict, List, Optional, Sequence

import numpy as np

from sac_jax import background, wandb_records
from sac_jax.background import BackgroundWrites
from sac_jax.metric_writers import Point, point_scalars
from sac_jax.messages import first_line
from sac_jax.run_dir import RunDirError
from sac_jax.whole_file import write_json

WANDB_JSON = "wandb.json"
INSTALL = 'pip install -e ".[track]"'


class TrackingUnavailable(ValueError):
    """`--track` without wandb installed."""


def check_available() -> None:
    """TrackingUnavailable (one line naming what to install) unless wandb can be imported."""
    if importlib.util.find_spec("wandb") is None:
        raise TrackingUnavailable(f"--track: needs wandb, which is not installed: {INSTALL} "
                                  "(or pip install wandb)")


def settings(project: str, entity: Optional[str], name: Optional[str],
             mode: Optional[str]) -> dict:
    """wandb.json's content for a new W&B run, with an id drawn here (8 lowercase letters and
    digits, as W&B's own)."""
    alphabet = string.ascii_lowercase + string.digits
    run_id = "".join(secrets.choice(alphabet) for _ in range(8))
    return {"id": run_id, "project": project, "entity": entity, "name": name, "mode": mode}


def save_settings(run_dir: str, tracked: dict) -> None:
    write_json(os.path.join(run_dir, WANDB_JSON), tracked)


def load_settings(run_dir: str) -> Optional[dict]:
    """wandb.json of a run directory, or None if the run is not tracked; `RunDirError` (one
    line naming the file) if it cannot be read."""
    path = os.path.join(run_dir, WANDB_JSON)
    if not os.path.exists(path):
        return None
    try:
        with open(path) as f:
            settings = json.load(f)
    except (OSError, ValueError) as error:
        raise RunDirError(f"{path}: not readable ({first_line(error)})") from None
    if not isinstance(settings, dict):
        raise RunDirError(f"{path}: not readable (a JSON object expected)")
    return settings


class WandbRun(BackgroundWrites):
    """One W&B run following a run directory. Started (or resumed, by the id in `tracked`)
    on the background thread, where the points are logged too: `history` (the points of the
    state the run starts from) first, then each `add_point`, skipping the points W&B already
    holds. `finish(summary, exit_code)` sets the summary and ends the W&B run."""

    def __init__(self, run_dir: str, tracked: dict, config: dict, history: Sequence[Point]):
        super().__init__()
        self._run = None
        self._next_step = 0
        self.submit(self._start, run_dir, dict(tracked), dict(config), list(history))

    def _start(self, run_dir: str, tracked: dict, config: dict, history: List[Point]) -> None:
        directory = os.environ.get("WANDB_DIR") or run_dir
        with background.SYNTAX_TREE_IMPORTS:  # both import modules that parse source as they load
            import wandb

            self._run = wandb.init(
                id=tracked["id"], resume="allow", project=tracked["project"],
                entity=tracked["entity"], name=tracked["name"] or os.path.basename(
                    os.path.abspath(run_dir)), mode=tracked["mode"], config=config,
                dir=directory, settings=wandb.Settings(silent=True, console="off"))
        held = earlier_offline_steps(directory, tracked["id"], self._run.dir) if (
            self._run.offline) else []
        self._next_step = max([self._run.step] + [s + 1 for s in held])
        for point in history:
            self._log(*point)

    def _log(self, step: int, means: Dict[str, float], eval_returns: np.ndarray) -> None:
        if step >= self._next_step:
            self._run.log(point_scalars(means, eval_returns), step=step)
            self._next_step = step + 1

    def add_point(self, step: int, means: Dict[str, float], eval_returns) -> None:
        self.submit(self._log, step, dict(means), np.array(eval_returns))

    def _finish(self, summary: Optional[dict], exit_code: int) -> None:
        if summary is not None:
            self._run.summary.update(summary)
        self._run.finish(exit_code=exit_code)

    def finish(self, summary: Optional[dict] = None, exit_code: int = 0) -> None:
        """Sets the summary (if given) and ends the W&B run, after every point is logged."""
        self.submit(self._finish, summary, exit_code)
        self.close()


def follow(run_dir: str, config: dict, history: Sequence[Point]) -> Optional[WandbRun]:
    """The W&B run following the run directory `run_dir` if it is tracked (has wandb.json),
    with `config` as its config and the points of `history` logged first; else None."""
    tracked = load_settings(run_dir)
    return None if tracked is None else WandbRun(run_dir, tracked, config, history)


def earlier_offline_steps(directory: str, run_id: str, files_dir: str) -> List[int]:
    """The steps run `run_id` holds in the local transaction logs under `directory` of the
    processes before this one (whose W&B files are in `files_dir`)."""
    mine = os.path.dirname(os.path.abspath(files_dir))
    return [step for path in wandb_records.logs(directory, run_id)
            if os.path.dirname(os.path.abspath(path)) != mine
            for step in wandb_records.steps(path)]
