"""A cap on glibc's malloc arenas, for the processes our scripts start.

glibc gives each thread that allocates an arena (a heap) of its own, up to 8 per core
(`M_ARENA_MAX`), and keeps what a thread frees in that thread's arena for its own later use.
A training process has many threads: XLA's, the checkpoint writer's, tensorstore's and orbax's.
Every periodic checkpoint allocates and frees a copy of the state, its packed arrays and
tensorstore's chunks in whichever of them does the work, so the freed copies pile up in different
arenas instead of being reused, and the process's peak resident memory grows past what it holds.

    arenas  = ARENAS_PER_CORE * cores      (glibc: 8 * cores)

Measured on 2 cores of an AMD EPYC (`fast`, 10,000 replay slots, 4,096 steps, a checkpoint at
most every 0.5 s; peak RSS, `summary.json`'s peak_host_bytes, against `sac_jax.memory`'s
estimate):

    64 seeds    glibc's 16 arenas 885-1,021 MB (estimate / peak 0.89-0.92; 3 runs),
                4 arenas 784 MB (0.97-0.98; 2 runs), 2 arenas 720-729 MB (1.04-1.05; 3 runs)
    1 seed      the README's command, cold: 732-780 MB (4 runs), 4 arenas 695-726 MB (4),
                2 arenas 650-695 MB (7)

Fewer arenas make threads wait for each other's allocations: with 2 (one per core) a cold
compile of `fast` took a median 12.2 s against 11.4 s (7 alternated runs each), with 4 a median
10.7 s (4 runs); training ran as fast with either. Hence 2 per core.

Only the command-line scripts set it (`sac_jax.cli.run_main`): a library imported into a user's
program leaves that program's allocator alone (the README's "Runs: watch, stop, resume" says
how to set MALLOC_ARENA_MAX there). A MALLOC_ARENA_MAX in the environment, which glibc read at start,
is the user's choice and is kept.
"""

from __future__ import annotations

import ctypes
import os
from typing import Optional

ARENAS_PER_CORE = 2
"""Arenas per core (the module docstring's measurements)."""
M_ARENA_MAX = -8
"""glibc's `mallopt` parameter number for the arena cap (malloc.h)."""


def cap_arenas(per_core: int = ARENAS_PER_CORE) -> Optional[int]:
    """Caps this process's malloc arenas at `per_core` times the cores it may run on, for the
    threads that allocate from now on. Returns the cap, or None where none was set: a C library
    other than glibc (macOS, musl), or MALLOC_ARENA_MAX set in the environment."""
    if per_core < 1:
        raise ValueError(f"per_core must be >= 1, got {per_core}")
    if os.environ.get("MALLOC_ARENA_MAX"):
        return None
    try:
        if not (os.confstr("CS_GNU_LIBC_VERSION") or "").startswith("glibc"):
            return None
        libc = ctypes.CDLL(None)  # the C library this process runs on
    except (ValueError, OSError):  # no such name on this system; no C library to load
        return None
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    cap = per_core * (cores or 1)
    return cap if libc.mallopt(M_ARENA_MAX, cap) == 1 else None
