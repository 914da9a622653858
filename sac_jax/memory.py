"""What a run needs in memory, what is available, and the refusal of a run that cannot fit.

The run's data comes from the shapes of its real initial state (`jax.eval_shape` of the vmapped
`init`, nothing computed or allocated), in two parts:

    replay  the replay buffers' data, all seeds (`RunnerState.buffer.data`)
    state   everything else a run carries: parameters, target networks, optimiser states,
            environments, the delivered actor, keys, metric sums and outputs

A run holds its state once while training, and while a checkpoint is written, a copy where there is
room for it (`copy_fits`: the copy and as much again free), so that training goes on during the
write (`run_checkpoint.CheckpointWriter`): a copy of the state with the replay slots filled so far
(`stored_slots`: at most `min(run_steps, buffer_size)` of each seed's buffer; on an accelerator
rounded up to a power of two), on the device that holds the state (the host's memory, on the CPU).
Without room, a checkpoint is written without a copy, while training waits (on the CPU, straight
from the state; from an accelerator, fetched to host memory). Once the program is compiled, two more
parts are known: the chunk's `temporaries` (XLA's memory analysis of the compiled program:
activations of the sampled batches, environment steps in flight), and on the CPU the `process`'s own
resident memory before the state is made (Python, JAX, the compiled programs: about 0.9 GB for the
MJX tasks, measured, not modelled). So

    peak = process + replay + state + checkpoint copy + temporaries
    checkpoint copy = state + replay * stored_slots / buffer_size
                    = 0        (where the copy does not fit; on an accelerator, where it is
                                at most IN_LINE_COPY_BYTES: fetched to the host in line)

Measured on the CPU (`fast`, 1 seed, peak RSS at 4M and 8M replay slots): 44.5 bytes per
44-byte slot (benchmarks/memory.py, BENCHMARKS.md, which also holds the estimate against the
measured peak). Before compiling (`check`), `process` and `temporaries` are left out: the
available memory already excludes what the process holds, and the data is what grows with
`--seeds` and `--buffer-size`. The available memory is the host's (`MemAvailable` of
/proc/meminfo) on a CPU, the device's free memory (`memory_stats()`: bytes_limit -
bytes_in_use) on an accelerator.
"""
from __future__ import annotations

import dataclasses
import os
import resource
import sys
from typing import Optional, Sequence, Tuple

import jax

from sac_jax.config import SACConfig

class MemoryRefused(ValueError):
    """A run that needs more memory than is available (one line naming both)."""


@dataclasses.dataclass(frozen=True)
class MemoryNeed:
    """Bytes of a run of `seeds` seeds: `replay` and `state` held once, `checkpoint` the copy a
    checkpoint takes, `temporaries` of the compiled chunk and the `process`'s own (0 where not
    known; see the module docstring), and `peak`, their sum."""

    seeds: int
    replay: int
    state: int
    checkpoint: int
    temporaries: int = 0
    process: int = 0

    @property
    def peak(self) -> int:
        return self.replay + self.state + self.checkpoint + self.temporaries + self.process

    @property
    def per_seed(self) -> int:
        return self.peak // self.seeds


def tree_bytes(tree) -> int:
    """Bytes of the arrays (or ShapeDtypeStructs) of `tree` (a PRNG key counts its key data)."""
    return sum(x.size * x.dtype.itemsize for x in jax.tree_util.tree_leaves(tree))


def stored_slots(filled: int, capacity: int, platform: str) -> int:
    """Replay slots of each seed a checkpoint's copy holds when `filled` are filled: on the CPU
    exactly those (cut from a view on the host); on an accelerator, where the slots are cut on
    the device before anything is copied and each new length compiles a small slicing program,
    `filled` rounded up to a power of two (at most `capacity`; the slots past `filled` are
    zeros), so a run compiles at most log2(capacity) of them."""
    if platform == "cpu" or filled <= 0:
        return max(filled, 0)
    return min(capacity, 1 << (filled - 1).bit_length())


IN_LINE_COPY_BYTES = 4 << 20
"""On an accelerator, a checkpoint's copy of at most this many bytes is not made on the device:
the state is fetched to host memory in line (`run_checkpoint.CheckpointWriter`), which for a
few megabytes takes about a millisecond, and the device holds no copy beside the next chunk
(H200, 1 seed of `fast`: the device copy made the model's estimate 1.31x the measured peak,
as the copy was fetched and freed before the next chunk's temporaries were allocated, or
not, depending on the host's timing)."""


def copy_fits(copy: int, free: Optional[int]) -> bool:
    """Whether a checkpoint's copy of `copy` bytes is made where `free` bytes are free (None:
    unknown): room for it and as much again (`run_checkpoint.CheckpointWriter`); else the
    checkpoint is written without a copy."""
    return free is None or 2 * copy <= free


def need(config: SACConfig, seeds: int, platform: Optional[str] = None, temporaries: int = 0,
         process: int = 0, available: Optional[int] = None) -> MemoryNeed:
    """The memory a run of `seeds` seeds of `config` needs on `platform` (default: JAX's
    default backend), from `jax.eval_shape` of its initial state, with the `temporaries` and
    `process` bytes given (`temporaries`, `process_bytes`); with the bytes `available` before
    the run, a checkpoint's copy counts only where it `copy_fits` beside the run's data, and
    on an accelerator only where it exceeds `IN_LINE_COPY_BYTES`."""
    from sac_jax.run_dir import state_template

    state = state_template(config, seeds)
    replay = tree_bytes(state.buffer.data)
    rest = tree_bytes(state) - replay
    platform = platform or jax.default_backend()
    slots = stored_slots(min(config.run_steps, config.buffer_size), config.buffer_size, platform)
    copy = rest + replay * slots // config.buffer_size
    if platform != "cpu" and copy <= IN_LINE_COPY_BYTES:
        copy = 0  # fetched to the host in line
    if available is not None and not copy_fits(copy, available - replay - rest - temporaries):
        copy = 0
    return MemoryNeed(seeds=seeds, replay=replay, state=rest, checkpoint=copy,
                      temporaries=temporaries, process=process)


def temporaries(programs: Sequence, device: Optional[jax.Device] = None,
                devices: int = 1) -> int:
    """`need`'s temporaries for `programs` (the compiled programs a chunk runs one after the
    other: `jax.stages.Compiled`s or `sac_jax.program_cache.CachedProgram`s, each over
    `devices` devices): XLA's temporary bytes of the largest of them (0 where the backend does
    not say), which are one device's, times `devices` on a CPU, whose devices all take the
    host's memory. (A CPU run of 64 seeds of `fast` over 2 devices, 2,048 steps: 894 MB at
    peak, estimated 833 MB with one device's temporaries, 876 MB with both.)"""
    try:
        largest = max(int(p.memory_analysis().temp_size_in_bytes) for p in programs)
    except Exception:  # a backend without the analysis
        return 0
    return largest * devices if (device or jax.local_devices()[0]).platform == "cpu" else largest


def process_bytes(device: Optional[jax.Device] = None) -> int:
    """`need`'s process bytes: on a CPU this process's resident bytes now (/proc/self/statm),
    elsewhere 0 (a device's free memory excludes them already)."""
    if (device or jax.local_devices()[0]).platform != "cpu":
        return 0
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


def _proc_bytes(path: str, key: str) -> Optional[int]:
    """The "key: N kB" entry of a /proc file in bytes; None where it cannot be read."""
    try:
        with open(path) as f:
            for line in f:
                if line.startswith(key + ":"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def peak_resident() -> int:
    """This process's peak resident bytes: /proc/self/status's VmHWM (the high-water mark of
    its own address space). Not `getrusage`'s ru_maxrss, which an exec keeps from the process
    it replaced: a run started by `subprocess` from a 3 GB pytest reported pytest's 3 GB. Where
    /proc is missing, ru_maxrss after all (kilobytes on Linux, bytes on macOS)."""
    peak = _proc_bytes("/proc/self/status", "VmHWM")
    if peak is not None:
        return peak
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak if sys.platform == "darwin" else peak * 1024


def _host_available() -> Optional[int]:
    return _proc_bytes("/proc/meminfo", "MemAvailable")


def available(device: Optional[jax.Device] = None) -> Tuple[Optional[int], str]:
    """(free bytes, where): the device's free memory if it reports a limit (an accelerator),
    else the host's available memory; None where neither can be read."""
    device = device or jax.local_devices()[0]
    stats = device.memory_stats() or {}
    if "bytes_limit" in stats:
        return stats["bytes_limit"] - stats.get("bytes_in_use", 0), device.platform
    return _host_available(), device.platform


def gigabytes(n: int) -> str:
    """Bytes as GB (one decimal), or MB below 1 GB."""
    return f"{n / 1e9:.1f} GB" if n >= 1e9 else f"{n / 1e6:.1f} MB"


def _parts(run: MemoryNeed) -> str:
    """'replay 1.7 GB + 0.2 GB state + 0.3 GB at a checkpoint' (or, without room for the
    copy, 'replay 1.7 GB + 0.2 GB state, checkpoints written in line without a copy')."""
    data = f"replay {gigabytes(run.replay)} + {gigabytes(run.state)} state"
    if run.checkpoint:
        return f"{data} + {gigabytes(run.checkpoint)} at a checkpoint"
    return f"{data}, checkpoints written in line without a copy"


def describe(run: MemoryNeed, free: Optional[int], where: str) -> str:
    """'replay 1.7 GB + 0.2 GB state + 0.3 GB at a checkpoint = 2.2 GB of 21.9 GB available on
    cpu'."""
    have = "unknown memory" if free is None else f"{gigabytes(free)} available"
    return f"{_parts(run)} = {gigabytes(run.peak)} of {have} on {where}"


def check(config: SACConfig, seeds: int) -> str:
    """The run's memory line (`describe`); `MemoryRefused` (one line: the need, what is
    available, the flags that shrink it) if its peak exceeds the available memory, a
    checkpoint's copy left out where it does not fit (`copy_fits`). Seeds split over several
    accelerators (`parallel.seed_devices`) are checked per device: each device's share of
    the seeds against the least free memory among them; a CPU's devices share the host's."""
    from sac_jax import parallel

    devices = parallel.seed_devices(seeds)
    free, where = available(devices[0])
    if where != "cpu" and len(devices) > 1:
        frees = [available(d)[0] for d in devices]
        free = None if None in frees else min(frees)
        seeds_each = seeds // len(devices)
        run = need(config, seeds_each, where, available=free)
        where = f"{where} (each of {len(devices)} devices, {seeds_each} seeds each)"
    else:
        run = need(config, seeds, where, available=free)
    if free is not None and run.peak > free:
        raise MemoryRefused(
            f"{seeds} seed(s) of buffer_size={config.buffer_size} need {gigabytes(run.peak)} "
            f"({_parts(run)}), {gigabytes(free)} available on {where}: lower --buffer-size or "
            "--seeds (or --no-memory-check to try anyway)")
    return describe(run, free, where)
