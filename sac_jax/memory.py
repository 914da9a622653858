"""What a run needs in memory, what is available, and the refusal of a run that cannot fit.

The need comes from the shapes of the run's real initial state (`jax.eval_shape` of the vmapped
`init`, nothing computed or allocated), in two parts:

    replay  the replay buffers' data, all seeds (`RunnerState.buffer.data`)
    state   everything else a run carries: parameters, target networks, optimiser states,
            environments, the delivered actor, keys, metric sums and outputs

A run holds its state once while training, and while a checkpoint is written, a copy:
on an accelerator with room for it, a device copy of the whole state (`run_checkpoint.CheckpointWriter`,
so the device trains on while the copy is written); on the CPU, where fetching device memory to
the host is a view, a host copy of the state with the replay slots filled so far, at most
`min(run_steps, buffer_size)` of each seed's buffer. So

    peak = replay + state + checkpoint copy
    checkpoint copy = state + replay                                (accelerator)
                    = state + replay * min(run_steps, buffer_size) / buffer_size   (CPU)

Measured on the CPU (`fast`, 1 seed, peak RSS at 4M and 8M replay slots): 44.3 bytes per
44-byte slot. The process's own memory (JAX, XLA, the compiled programs: about 0.8 GB on the
CPU) comes on top and is not modelled. The available memory is the host's (`MemAvailable` of
/proc/meminfo) on a CPU, the device's free memory (`memory_stats()`: bytes_limit -
bytes_in_use) on an accelerator.
"""

from __future__ import annotations

import dataclasses
from typing import Optional, Tuple

import jax

from sac_jax.config import SACConfig

class MemoryRefused(ValueError):
    """A run that needs more memory than is available (one line naming both)."""


@dataclasses.dataclass(frozen=True)
class MemoryNeed:
    """Bytes of a run of `seeds` seeds: `replay` and `state` held once, `checkpoint` the copy a
    checkpoint takes (see the module docstring), and `peak`, their sum."""

    seeds: int
    replay: int
    state: int
    checkpoint: int

    @property
    def peak(self) -> int:
        return self.replay + self.state + self.checkpoint

    @property
    def per_seed(self) -> int:
        return self.peak // self.seeds


def _bytes(tree) -> int:
    """Bytes of the arrays (or ShapeDtypeStructs) of `tree` (a PRNG key counts its key data)."""
    return sum(x.size * x.dtype.itemsize for x in jax.tree_util.tree_leaves(tree))


def need(config: SACConfig, seeds: int, platform: Optional[str] = None) -> MemoryNeed:
    """The memory a run of `seeds` seeds of `config` needs on `platform` (default: JAX's
    default backend), from `jax.eval_shape` of its initial state."""
    from sac_jax.run_dir import state_template

    state = state_template(config, seeds)
    replay = _bytes(state.buffer.data)
    rest = _bytes(state) - replay
    if (platform or jax.default_backend()) == "cpu":
        copied = replay * min(config.run_steps, config.buffer_size) // config.buffer_size
    else:
        copied = replay
    return MemoryNeed(seeds=seeds, replay=replay, state=rest, checkpoint=rest + copied)


def _host_available() -> Optional[int]:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


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


def describe(run: MemoryNeed, free: Optional[int], where: str) -> str:
    """'replay 1.7 GB + 0.2 GB state + 0.3 GB at a checkpoint = 2.2 GB of 21.9 GB available on
    cpu'."""
    have = "unknown memory" if free is None else f"{gigabytes(free)} available"
    return (f"replay {gigabytes(run.replay)} + {gigabytes(run.state)} state + "
            f"{gigabytes(run.checkpoint)} at a checkpoint = {gigabytes(run.peak)} of {have} on "
            f"{where}")


def check(config: SACConfig, seeds: int) -> str:
    """The run's memory line (`describe`); `MemoryRefused` (one line: the need, what is
    available, the flags that shrink it) if its peak exceeds the available memory."""
    free, where = available()
    run = need(config, seeds, where)
    if free is not None and run.peak > free:
        raise MemoryRefused(
            f"{seeds} seed(s) of buffer_size={config.buffer_size} need {gigabytes(run.peak)} "
            f"(replay {gigabytes(run.replay)} + {gigabytes(run.state)} state + "
            f"{gigabytes(run.checkpoint)} at a checkpoint), {gigabytes(free)} available on "
            f"{where}: lower --buffer-size or --seeds (or --no-memory-check to try anyway)")
    return describe(run, free, where)
