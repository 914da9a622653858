"""The scripts' cap on glibc's malloc arenas (`sac_jax.malloc_arenas`): threads that allocate
after it share at most the capped number of arenas, counted by glibc's own `malloc_info`; a
MALLOC_ARENA_MAX of the user's is kept; `run_main` sets the cap before the script's `main`."""

import os

import pytest

from sac_jax import cli, malloc_arenas
from tests.subprocess_json import run_json

glibc = pytest.mark.skipif(
    not (hasattr(os, "confstr") and (os.confstr("CS_GNU_LIBC_VERSION") or "").startswith("glibc")),
    reason="malloc arenas are glibc's")

ARENAS = r"""
import ctypes, json, os, sys, tempfile, threading
from sac_jax import malloc_arenas

libc = ctypes.CDLL(None)
libc.fopen.restype = ctypes.c_void_p
per_core = int(sys.argv[1])
cap = malloc_arenas.cap_arenas(per_core) if per_core else None
cores = len(os.sched_getaffinity(0))
threads = 2 * cores + 2  # more than a cap of 1 per core, whatever the cores
barrier = threading.Barrier(threads)
held = []

def allocate():  # every thread allocates while all of them are alive
    barrier.wait()
    held.append([bytearray(1 << 16) for _ in range(8)])
    barrier.wait()

workers = [threading.Thread(target=allocate) for _ in range(threads)]
for worker in workers:
    worker.start()
for worker in workers:
    worker.join()
path = tempfile.mktemp()
stream = libc.fopen(path.encode(), b"w")
libc.malloc_info(0, ctypes.c_void_p(stream))
libc.fclose(ctypes.c_void_p(stream))
with open(path) as f:
    heaps = f.read().count("<heap nr=")
os.remove(path)
print(json.dumps({"cap": cap, "arenas": heaps, "cores": cores}))
"""


def arenas(per_core: int, **env) -> dict:
    """A fresh process's arenas after 2 threads per core, and 2 more, allocated at once
    (per_core 0: no cap)."""
    return run_json(["-c", ARENAS, str(per_core)], **env)


@glibc
@pytest.mark.skipif("MALLOC_ARENA_MAX" in os.environ,
                    reason="MALLOC_ARENA_MAX set for the whole suite: glibc's cap, not ours")
def test_threads_share_the_capped_arenas():
    capped = arenas(1)
    assert capped["cap"] == capped["cores"]
    assert 1 <= capped["arenas"] <= capped["cap"]
    # without the cap the same threads take more arenas: glibc's default is 8 per core
    free = arenas(0)
    assert free["cap"] is None
    assert free["arenas"] > capped["cap"], free


@glibc
def test_a_users_malloc_arena_max_is_kept():
    result = arenas(1, MALLOC_ARENA_MAX="3")
    assert result["cap"] is None
    assert result["arenas"] <= 3  # glibc's reading of the variable, not ours


def test_per_core_below_one_is_refused():
    with pytest.raises(ValueError, match="per_core must be >= 1, got 0"):
        malloc_arenas.cap_arenas(0)


def test_run_main_caps_the_arenas_before_main(monkeypatch):
    calls = []
    monkeypatch.setattr(malloc_arenas, "cap_arenas", lambda: calls.append("cap"))
    with pytest.raises(SystemExit) as stop:
        cli.run_main(lambda: calls.append("main") or 0)
    assert stop.value.code == 0
    assert calls == ["cap", "main"]


@pytest.mark.parametrize("confstr", [None, "unknown", "musl"])
def test_no_cap_where_the_c_library_is_not_glibc(monkeypatch, confstr):
    """Windows has no os.confstr, macOS no CS_GNU_LIBC_VERSION (ValueError), and another C
    library another answer: nothing is set, and nothing fails."""
    monkeypatch.delenv("MALLOC_ARENA_MAX", raising=False)
    if confstr is None:
        monkeypatch.delattr(os, "confstr", raising=False)
    else:
        def answer(name):
            if confstr == "unknown":
                raise ValueError("unrecognized configuration name")
            return confstr
        monkeypatch.setattr(os, "confstr", answer)
    monkeypatch.setattr(malloc_arenas.ctypes, "CDLL", lambda *a: pytest.fail("loaded a libc"))
    assert malloc_arenas.cap_arenas() is None
