"""What the command-line scripts share: a tyro command line generated from a dataclass, whose bad
input ends with one line on stderr and no traceback (exit 2); a missing dependency ends the same
way with exit 1.

tyro reports bad input in multi-line panels; `parse` turns each report into one line naming the
flag and the value. It uses tyro's parse-error hook (`tyro._errors.on_parse_error`), which tyro
marks experimental: tyro is pinned to an exact version in pyproject.toml, and
tests/test_cli.py checks every kind of report.
"""

from __future__ import annotations

import sys
from typing import Optional, Sequence, Type, TypeVar

import tyro
from tyro import _errors

T = TypeVar("T")


class MissingDependency(Exception):
    """A library or system package that the requested work needs is not available (exit 1)."""


class UsageError(ValueError):
    """Bad command-line input, as one line."""


def _one_line(event: _errors.ParseErrorEvent) -> None:
    """tyro's parse-error hook: raises UsageError with one line for `event`."""
    if isinstance(event, _errors.InstantiationFailure):
        message = " ".join(str(event.message).split())
        raise UsageError(message if event.argument is None else f"{event.argument.display_name()}: {message}")
    if isinstance(event, _errors.InvalidChoice):
        raise UsageError(f"{event.argument.display_name()}={event.value!r}: must be one of "
                         f"{list(event.choices)}")
    if isinstance(event, _errors.BadValue):
        if event.offending_value is None:
            raise UsageError(f"{event.argument.display_name()}: expected a value")
        raise UsageError(f"{event.argument.display_name()}: takes no value, got {event.offending_value!r}")
    if isinstance(event, _errors.UnrecognizedArgs):
        raise UsageError(f"unrecognized arguments: {' '.join(event.tokens)} (see --help)")
    if isinstance(event, _errors.MissingArgs):
        names = [missing.arg.display_name() for missing in event.missing_arguments]
        raise UsageError(f"missing {', '.join(names)} (see --help)")
    raise UsageError(f"bad command line ({type(event).__name__}; see --help)")


def parse(cls: Type[T], argv: Optional[Sequence[str]] = None, *, default: Optional[T] = None,
          description: Optional[str] = None) -> T:
    """`tyro.cli(cls)` on `argv` (default: sys.argv[1:]), with `default` as the defaults when
    given; UsageError (one line) for bad input. `--help` prints and exits as usual."""
    argv = sys.argv[1:] if argv is None else list(argv)
    kwargs = {} if default is None else {"default": default}
    with _errors.on_parse_error(_one_line):
        return tyro.cli(cls, args=argv, description=description, **kwargs)


def positive(name: str, value: int) -> None:
    """ValueError naming the flag `--name` unless `value` is an integer >= 1."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ValueError(f"--{name.replace('_', '-')}={value!r}: must be a positive integer")


def fail(error: Exception, code: int) -> int:
    """Prints `error` as one 'error: ...' line on stderr; returns the exit code `code`."""
    print(f"error: {error}", file=sys.stderr)
    return code
