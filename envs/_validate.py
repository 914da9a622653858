"""Checks of user-supplied environment options; each error names the offending value."""

import math
import numbers


def positive_int(option: str, value) -> int:
    """Return ``value`` if it is an int >= 1 (bools excluded)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
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
