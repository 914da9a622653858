"""Sending a script real signals while it runs, for the tests of scripts/train.py and
scripts/sweep.py."""

from __future__ import annotations

import os
import signal

from sac_jax import cli
from sac_jax.cli import LeaveNow


def interrupted_main(script, argv, signals: int = 1) -> int:
    """`script.main(argv)` sent `signals` real SIGINTs at its first evaluation point (from its
    progress line), while the run goes on; its exit code (a stop at once, `LeaveNow`, gives
    its code: the process would then exit without waiting for the device)."""
    line = cli.progress_line  # `cli.train_in_dir` prints each point's line

    def progress_then_interrupt(*args):
        for _ in range(signals):
            os.kill(os.getpid(), signal.SIGINT)
        return line(*args)

    cli.progress_line = progress_then_interrupt
    try:
        return script.main(argv)
    except LeaveNow as leave:
        return leave.code
    finally:
        cli.progress_line = line
