"""What the command-line scripts share: bad input ends with one line on stderr, no traceback
(exit 2); so does a missing dependency (exit 1)."""

from __future__ import annotations

import argparse


class MissingDependency(Exception):
    """A library or system package that the requested work needs is not available (exit 1)."""


class Parser(argparse.ArgumentParser):
    """argparse whose errors are one line on stderr (no usage block), exit code 2."""

    def error(self, message):
        self.exit(2, f"error: {message}\n")


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {value}")
    return value
