"""What a run needs in memory, what is available, and the refusal of a run that cannot fit.

The need comes from the shapes of the run's real initial state (`jax.eval_shape` of the vmapped
`init`, nothing computed or allocated), in two parts:

    replay  the replay buffers' data, all seeds (`RunnerState.buffer.data`)
    state   everything else a run carries: parameters, target networks, optimiser states,
            environments, the delivered actor, keys, metric sums and outputs

A run holds its state once while training. While a checkpoint is written it holds a second
copy (`run_dir.CheckpointWriter` copies the state, so the device trains on while the copy is
written; a device without room for the copy has it fetched to host memory instead), so the
peak is taken as twice the state: `peak = 2 (replay + state)`. The available memory is the
host's (`MemAvailable` of /proc/meminfo) on a CPU, the device's free memory
(`memory_stats()`: bytes_limit - bytes_in_use) on an accelerator.
"""

from __future__ import annotations

import dataclasses
from typing import Optional, Tuple

import jax

from sac_jax.config import SACConfig

COPIES_AT_PEAK = 2
"""Copies of the run's state at its peak: the state and a checkpoint's copy of it."""


class MemoryRefused(ValueError):
    """A run that needs more memory than is available (one line naming both)."""


@dataclasses.dataclass(frozen=True)
class MemoryNeed:
    """Bytes of a run of `seeds` seeds: `replay` and `state` held once (see the module
    docstring), and `peak`, with a checkpoint's copy."""

    seeds: int
    replay: int
    state: int

    @property
    def peak(self) -> int:
        return COPIES_AT_PEAK * (self.replay + self.state)

    @property
    def per_seed(self) -> int:
        return self.peak // self.seeds


def _bytes(tree) -> int:
    """Bytes of the arrays (or ShapeDtypeStructs) of `tree` (a PRNG key counts its key data)."""
    return sum(x.size * x.dtype.itemsize for x in jax.tree_util.tree_leaves(tree))


def need(config: SACConfig, seeds: int) -> MemoryNeed:
    """The memory a run of `seeds` seeds of `config` needs, from `jax.eval_shape` of its
    initial state."""
    from sac_jax.run_dir import state_template

    state = state_template(config, seeds)
    replay = _bytes(state.buffer.data)
    return MemoryNeed(seeds=seeds, replay=replay, state=_bytes(state) - replay)


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
    """'replay 1.7 GB + 0.2 GB state, x2 at a checkpoint: 3.8 GB of 21.9 GB available on cpu'."""
    have = "unknown memory" if free is None else f"{gigabytes(free)} available"
    return (f"replay {gigabytes(run.replay)} + {gigabytes(run.state)} state, x{COPIES_AT_PEAK} at "
            f"a checkpoint: {gigabytes(run.peak)} of {have} on {where}")


def check(config: SACConfig, seeds: int) -> str:
    """The run's memory line (`describe`); `MemoryRefused` (one line: the need, what is
    available, the flags that shrink it) if its peak exceeds the available memory."""
    run = need(config, seeds)
    free, where = available()
    if free is not None and run.peak > free:
        raise MemoryRefused(
            f"{seeds} seed(s) of buffer_size={config.buffer_size} need {gigabytes(run.peak)} at "
            f"a checkpoint (replay {gigabytes(run.replay)} + {gigabytes(run.state)} state, x"
            f"{COPIES_AT_PEAK}), {gigabytes(free)} available on {where}: lower --buffer-size or "
            "--seeds (or --no-memory-check to try anyway)")
    return describe(run, free, where)
