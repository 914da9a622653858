"""scripts/train.py, killed by SIGKILL at the checkpoint of an evaluation point, once that point
is in TensorBoard's event files: the window in which a resumed run computes again a point that
TensorBoard already holds (the checkpoint on disk is the previous point's). W&B's local log of
a tracked run holds what W&B wrote by then (it buffers its writes: a point may be there or not).

    python -m tests.killed_run STEP ARGS...     # ARGS: scripts/train.py's command line

Run it in a process of its own (tests/test_train_script.py); its exit status is -9 when it was
killed there, 3 if the point never reached the files (or a tracked run's W&B run never
started), and scripts/train.py's own if the run never came to STEP.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time

from sac_jax import run_checkpoint, tracking, wandb_records
from scripts import train as train_script


def tensorboard_steps(directory: str) -> set:
    """The steps of the events in the event files of `directory` (none if it is missing)."""
    from tensorboard.backend.event_processing.event_file_loader import LegacyEventFileLoader

    names = os.listdir(directory) if os.path.isdir(directory) else []
    return {event.step for name in names
            for event in LegacyEventFileLoader(os.path.join(directory, name)).Load()}


def wandb_steps(run_dir_path: str) -> set:
    """The steps in the local W&B logs of the run directory's W&B run (none if untracked)."""
    tracked = tracking.load_settings(run_dir_path)
    if tracked is None:
        return set()
    directory = os.environ.get("WANDB_DIR") or run_dir_path
    return {step for path in wandb_records.logs(directory, tracked["id"])
            for step in wandb_records.steps(path)}


def kill_at_checkpoint(step: int, timeout_s: float = 60.0) -> None:
    """Makes `CheckpointWriter.save` of the evaluation point at `step` wait for that point in
    the run directory's TensorBoard files (and, for a tracked run, for its W&B run to have
    started, so that each process leaves a W&B log), then SIGKILL this process before saving."""
    save = run_checkpoint.CheckpointWriter.save
    start = tracking.WandbRun._start
    wandb_started = threading.Event()

    def start_and_tell(run, *args):
        start(run, *args)
        wandb_started.set()

    def save_or_die(writer, runner, position):
        if max(position.walls, default=None) == step:
            events = os.path.join(writer._run_dir, "tensorboard")
            deadline = time.monotonic() + timeout_s
            tracked = tracking.load_settings(writer._run_dir) is not None
            while step not in tensorboard_steps(events) or (
                    tracked and not wandb_started.is_set()):
                if time.monotonic() > deadline:
                    os._exit(3)
                time.sleep(0.05)
            writer._collect(wait=True)  # the previous point's checkpoint is on disk
            os.kill(os.getpid(), signal.SIGKILL)
        return save(writer, runner, position)

    run_checkpoint.CheckpointWriter.save = save_or_die
    tracking.WandbRun._start = start_and_tell
    run_checkpoint.MIN_INTERVAL_S = 0.0  # a checkpoint at every point


if __name__ == "__main__":
    kill_at_checkpoint(int(sys.argv[1]))
    from sac_jax.cli import run_main

    run_main(lambda: train_script.main(sys.argv[2:]))
