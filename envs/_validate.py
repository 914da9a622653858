"""Checks of user-supplied values (environment options, sizes, names), shared by `envs` and
`sac_jax`; each error names the offending value."""

import difflib
import math
import numbers
from typing import Sequence


def is_integer(value) -> bool:
    """Whether `value` is an integer (Python's or NumPy's), bools excluded."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def is_positive_int(value) -> bool:
    """Whether `value` is an integer >= 1 (`is_integer`)."""
    return is_integer(value) and value >= 1


def unknown_name(kind: str, name: str, candidates: Sequence[str], otherwise: str,
                 prefix: str = "") -> ValueError:
    """The one-line error for an unknown `name` of `kind`: "unknown KIND 'NAME'; did you mean
    ...?" naming up to 3 close `candidates` (each shown after `prefix`, matched against `name`
    without it), else `otherwise`."""
    close = difflib.get_close_matches(name[len(prefix):], candidates, n=3, cutoff=0.6)
    hint = f"did you mean {', '.join(prefix + c for c in close)}?" if close else otherwise
    return ValueError(f"unknown {kind} {name!r}; {hint}")


def positive_int(option: str, value) -> int:
    """Return ``value`` if it is an int >= 1 (bools excluded)."""
    if not is_integer(value):
        raise TypeError(f"option {option} must be an int, got {value!r}")
    if value < 1:
        raise ValueError(f"option {option} must be >= 1, got {value!r}")
    return int(value)


def finite_float(option: str, value, minimum: float = -math.inf) -> float:
    """Return ``float(value)`` if it is a finite real number >= ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"option {option} must be a real number, got {value!r}")
    if not math.isfinite(value) or value < minimum:
        raise ValueError(f"option {option} must be finite and >= {minimum}, got {value!r}")
    return float(value)
