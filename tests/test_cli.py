"""sac_jax/cli.py: every kind of bad command line tyro reports becomes one line naming the flag
and the value (UsageError), and good input parses as tyro parses it; a stop at once says why in
one line and leaves with the signal's exit code; a script whose reader has gone exits quietly."""

import dataclasses
import os
import signal
import subprocess
import sys
from typing import Literal, Optional, Tuple

import pytest
import tyro

from sac_jax import compilation_cache
from sac_jax.cli import CompileNotice, LeaveNow, StopRequest, UsageError, parse, positive
from sac_jax.run import DeviceBusy
from tests.subprocess_json import ROOT


@dataclasses.dataclass(frozen=True)
class Args:
    """A command line with one argument of each kind."""

    run: tyro.conf.Positional[str]
    """A required positional."""
    count: int = 1
    which: Literal["a", "b"] = "a"
    sizes: Tuple[int, ...] = (2, 2)
    flag: bool = False
    scale: Optional[float] = None

    def __post_init__(self):
        positive("count", self.count)


@pytest.mark.parametrize("argv, message", [
    (["r", "--count", "x"], "--count: invalid literal for int() with base 10: 'x'"),
    (["r", "--count", "0"], "--count=0: must be a positive integer"),
    (["r", "--which", "c"], "--which='c': must be one of ['a', 'b']"),
    (["r", "--count"], "--count: expected a value"),
    (["r", "--sizes", "2", "y"], "--sizes: Could not find valid parse for arguments: ['2', 'y']"),
    (["r", "--nope", "3"], "unrecognized arguments: --nope 3 (see --help)"),
    (["r", "--flag", "yes"], "unrecognized arguments: yes (see --help)"),
    ([], "missing run (see --help)"),
])
def test_each_kind_of_bad_input_is_one_line(argv, message):
    with pytest.raises(UsageError) as error:
        parse(Args, argv)
    assert str(error.value) == message and "\n" not in str(error.value)


def test_good_input_and_defaults():
    assert parse(Args, ["r", "--count", "3", "--which", "b", "--sizes", "4", "5", "--flag",
                        "--scale", "None"]) == Args("r", 3, "b", (4, 5), True, None)
    assert parse(Args, ["r"], default=Args("x", count=7)) == Args("r", count=7)


def test_positive_rejects_bools_and_non_positive():
    for value in (0, -1, True, 1.5):
        with pytest.raises(ValueError, match="must be a positive integer"):
            positive("n", value)
    positive("n", 1)


@pytest.mark.parametrize("signum, error, why, code", [
    (signal.SIGINT, KeyboardInterrupt(), "SIGINT again: stopped at once", 130),
    (signal.SIGTERM, DeviceBusy("still running a chunk 10 s after the stop"),
     "SIGTERM: still running a chunk 10 s after the stop; stopped without it", 143)])
def test_a_stop_at_once_says_why_in_one_line_and_leaves_with_the_signals_code(
        capsys, signum, error, why, code):
    stop = StopRequest()
    stop(signum, None)  # the first signal asks for a stop after the chunk
    with pytest.raises(LeaveNow) as leave:
        stop.leave_now(error, "continue with --resume out")
    assert leave.value.code == code
    assert capsys.readouterr().err.splitlines()[-1] == f"error: {why}; continue with --resume out"


@pytest.mark.parametrize("directory, where", [
    ("/cache/jax", "cached in /cache/jax for later runs"),
    (None, "no cache: every run compiles them")])
def test_the_compile_line_says_where_the_programs_go_and_ends_with_the_seconds(
        capsys, monkeypatch, directory, where):
    monkeypatch.setattr(compilation_cache, "active_directory", lambda: directory)
    notice = CompileNotice()
    assert capsys.readouterr().out == f"compiling the programs ({where}) ..."  # line left open
    notice.ready(9.46)
    notice.close()  # the line is ended already
    assert capsys.readouterr().out == " 9.5 s\n"


def test_a_compile_line_left_open_is_ended_before_an_error(capsys, monkeypatch):
    monkeypatch.setattr(compilation_cache, "active_directory", lambda: None)
    notice = CompileNotice()
    capsys.readouterr()
    notice.close()  # no ready: e.g. the compile failed
    notice.close()
    assert capsys.readouterr().out == "\n"


def test_a_signal_during_the_compile_ends_its_line_first(capsys, monkeypatch):
    """SIGINT while the programs compile: the open line ends before the signal's message, and
    the seconds come on a line of their own."""
    monkeypatch.setattr(compilation_cache, "active_directory", lambda: None)
    stop = StopRequest()
    notice = stop.notice = CompileNotice()
    stop(signal.SIGINT, None)
    notice.ready(9.46)
    captured = capsys.readouterr()
    assert captured.out == ("compiling the programs (no cache: every run compiles them) ...\n"
                            "programs ready after 9.5 s\n")
    assert captured.err.startswith("SIGINT: stopping after the current chunk")


@pytest.mark.parametrize("script", ["train", "sweep", "evaluate", "render"])
def test_a_script_whose_reader_has_gone_exits_1_without_a_traceback(script):
    """`python scripts/train.py --help | head -1`: the reader of standard output is gone (here
    before the first write), so a write fails with EPIPE; the script ends with exit 1 and
    nothing on stderr, not a BrokenPipeError traceback."""
    read, write = os.pipe()
    os.close(read)
    try:
        proc = subprocess.run([sys.executable, f"scripts/{script}.py", "--help"], cwd=ROOT,
                              stdout=write, stderr=subprocess.PIPE, text=True, timeout=300)
    finally:
        os.close(write)
    assert (proc.returncode, proc.stderr) == (1, "")
