"""A cap on glibc's malloc arenas, for the processes our scripts start.

glibc gives each thread that allocates an arena (a heap) of its own, up to 8 per core
(`M_ARENA_MAX`), and keeps what a thread frees in that thread's arena for its own later use.
A training process has many threads: XLA's, the checkpoint writer's, tensorstore's and orbax's.
Every periodic checkpoint allocates and frees a copy of the state, its packed arrays and
tensorstore's chunks in whichever of them does the work, so the freed copies pile up in different
arenas instead of being reused, and the process's peak resident memory grows past what it holds.

    arenas  = ARENAS_PER_CORE * cores      (glibc: 8 * cores)

Measured on 2 cores of an AMD EPYC (`fast`, 64 seeds of 10,000 replay slots; peak RSS,
`summary.json`'s peak_host_bytes, and `sac_jax.memory`'s estimate over it):

    4,096 steps, a checkpoint at most every 0.5 s:
        glibc's 16 arenas  885-1,021 MB (0.89-0.92; 3 runs)
        4 arenas           784-788 MB (0.97-0.98; 2 runs)
        2 arenas           720-729 MB (1.04-1.05; 3 runs)
    the whole run (14,336 steps, a checkpoint at most every 5 s):
        glibc's 16 arenas  1,067 MB (0.76; benchmarks/results/memory.json of 2026-11-30)
        4 arenas           860-972 MB (0.88-0.91; 2 runs; 914 MB, 0.89, with a malloc_trim
                           after each checkpoint's write)
        2 arenas           790 MB (0.98; 1 run)

Fewer arenas make threads wait for each other's allocations, and compiling is many threads'
work: in 5 alternated pairs of cold runs of the README's command, 2 arenas compiled for a
median 11.0 s against 10.3 s with 4 (1.2 s longer in the median pair), where 4 and glibc's 16
compiled alike (10.7 s against 11.4 s, medians of 4 and 7 runs). Training ran as fast with
either. Hence 2 per core: less memory than glibc's default at no cost in compile time (the
README's command, 1 seed, peaked at 688-736 MB over those 5 runs, against 732-780 MB with 16
arenas), where 1 per core would save more (639-655 MB) for a second of every cold start.

Only the command-line scripts set it (`sac_jax.cli.run_main`): a library imported into a user's
program leaves that program's allocator alone (the README's "Runs: watch, stop, resume" says
how to set MALLOC_ARENA_MAX there). A MALLOC_ARENA_MAX in the environment, which glibc read at
start, is the user's choice and is kept.
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
    other than glibc (macOS, Windows, musl), or MALLOC_ARENA_MAX set in the environment."""
    if per_core < 1:
        raise ValueError(f"per_core must be >= 1, got {per_core}")
    if os.environ.get("MALLOC_ARENA_MAX"):
        return None
    try:
        libc_version = os.confstr("CS_GNU_LIBC_VERSION") or ""
    except (AttributeError, ValueError, OSError):  # no confstr (Windows); no such name (macOS)
        return None
    if not libc_version.startswith("glibc"):
        return None
    libc = ctypes.CDLL(None)  # the C library this process runs on
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    cap = per_core * (cores or 1)
    return cap if libc.mallopt(M_ARENA_MAX, cap) == 1 else None
