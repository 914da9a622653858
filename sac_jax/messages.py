"""What an error says, in one line, for the one-line messages the scripts end with."""

from __future__ import annotations

import os
import re


def first_line(error: BaseException) -> str:
    """The first line of `error`'s message (its type's name if it has none), at most 200
    characters."""
    return (str(error).strip().splitlines() or [type(error).__name__])[0][:200]


def os_reason(error: BaseException) -> str:
    """The operating system's words for a failed write: OSError's ("No space left on
    device"), or those of the `[os_error_code='N']` that tensorstore's errors end with; else
    `first_line`."""
    if isinstance(error, OSError) and error.strerror:
        return error.strerror
    code = re.search(r"os_error_code='(\d+)'", str(error))
    return os.strerror(int(code.group(1))) if code else first_line(error)
