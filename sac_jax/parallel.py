"""Spreading training over devices: a `jax.sharding.Mesh` with one named axis; seeds split by
sharding their axis, one run split data parallel with `jax.shard_map`.

Seeds over devices (axis "seeds"): the S independent runs of `jax.vmap(train)` are split into
D groups of S/D, one per device, by sharding the seed axis (`NamedSharding`); the program is
the same, and the devices never communicate.

Data parallel (axis "data"): one run, spread over D devices. Device d steps num_envs/D of the
environments, keeps its own replay buffer of buffer_size/D transitions, and draws batch_size/D
of each minibatch from it. Every update averages its gradients and losses over the axis
(`config.data_parallel_axis`, see `sac_jax.updates`), so a global update on D shares of B/D
equals the update on the whole batch of B, and the learner state stays identical on all
devices. Every branch that holds an update depends only on iteration counts, which all devices
share, so all of them reach each collective. The learner state is initialised from the run's
key on every device; device 0 also uses the run's key for its environments, buffer sampling and
noise, device d > 0 uses `fold_in(key, d)`, so on a one-device mesh the run is
`make_train(config)`'s (up to float32 rounding: the compiled program differs).

Meshes may span the devices of several processes (hosts): call `jax.distributed.initialize()`
first, then build the mesh from `jax.devices()` (docs/parallel.md).
"""

from __future__ import annotations

from typing import Callable, Dict, Optional, Sequence

import jax
import jax.numpy as jnp
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

from sac_jax.config import SACConfig
from sac_jax.train import METRIC_NAMES, RunnerState, TrainParts, make_train_parts

SEEDS = "seeds"
DATA = "data"
SHARDED_FIELDS = ("num_envs", "buffer_size", "batch_size", "learning_starts", "eval_every")
"""Config sizes a data-parallel run divides among its devices."""
PER_DEVICE_FIELDS = ("env", "buffer", "key", "sums", "outputs")
"""`RunnerState` fields that each device of a data-parallel run holds for itself."""


def make_mesh(axis: str, devices: Optional[Sequence[jax.Device]] = None) -> Mesh:
    """A one-axis mesh named `axis` over `devices` (default: all devices of all processes)."""
    devices = jax.devices() if devices is None else list(devices)
    return Mesh(devices, (axis,))


def _axis(mesh: Mesh) -> str:
    """The name of the mesh's only axis."""
    if len(mesh.axis_names) != 1:
        raise ValueError(f"mesh axes {mesh.axis_names}: need a mesh with exactly one axis")
    return mesh.axis_names[0]


# ---------------------------------------------------------------------------- seeds
def over_seeds(fn: Callable, mesh: Mesh, in_axes=0, out_axes=0, donate: bool = False
               ) -> Callable:
    """`jax.jit(jax.vmap(fn, in_axes, out_axes))` with every mapped (seeds) axis of the arguments
    and results split over the mesh's axis, and unmapped (None) parts, such as the counters of
    `sac_jax.train.SEED_AXES`, held whole on every device: each device runs `jax.vmap(fn)` on
    its S/D seeds. S must be a multiple of the number of devices D. `donate` donates the
    (single) argument's buffers.

    The split is stated as `NamedSharding`s of the inputs and outputs and left to XLA's
    partitioner (seeds never communicate, so it inserts no collective). `jax.shard_map` would
    say the same thing, but XLA's GPU compiler of jax 0.11.2 crashes on the shard_mapped
    training program (BENCHMARKS.md), while this form compiles and runs on 2 GPUs."""
    split, whole = NamedSharding(mesh, P(_axis(mesh))), NamedSharding(mesh, P())
    shardings = lambda axes: jax.tree_util.tree_map(
        lambda axis: whole if axis is None else split, axes, is_leaf=lambda axis: axis is None)
    return jax.jit(jax.vmap(fn, in_axes, out_axes), in_shardings=shardings(in_axes),
                   out_shardings=shardings(out_axes), donate_argnums=(0,) if donate else ())


def seeds_program(fn: Callable, seeds: int, in_axes=0, out_axes=0, donate: bool = False
                  ) -> Callable:
    """`over_seeds` on all local devices when there are several and they divide `seeds`;
    otherwise the plain `jax.jit(jax.vmap(fn, in_axes, out_axes))` (the same program as before
    on one device)."""
    devices = jax.local_devices()
    if len(devices) > 1 and seeds % len(devices) == 0:
        return over_seeds(fn, make_mesh(SEEDS, devices), in_axes, out_axes, donate)
    return jax.jit(jax.vmap(fn, in_axes, out_axes), donate_argnums=(0,) if donate else ())


# ---------------------------------------------------------------------------- data parallel
def local_config(config: SACConfig, num_devices: int, axis: str = DATA) -> SACConfig:
    """One device's share of a data-parallel run of `config` over `num_devices` devices: the
    `SHARDED_FIELDS` divided by D (each must be a multiple of D), the same number of iterations
    and evaluations, and gradients averaged over `axis`."""
    if isinstance(num_devices, bool) or not isinstance(num_devices, int) or num_devices < 1:
        raise ValueError(f"num_devices={num_devices!r}: must be a positive integer")
    for field in SHARDED_FIELDS:
        value = getattr(config, field)
        if value % num_devices:
            raise ValueError(f"SACConfig.{field}={value}: must be a multiple of the "
                             f"{num_devices} devices of the data-parallel run")
    shares = {field: getattr(config, field) // num_devices for field in SHARDED_FIELDS}
    total = shares["learning_starts"] + config.num_evals * shares["eval_every"]
    return config.replace(**shares, total_steps=total, data_parallel_axis=axis)


def _runner_specs(axis: str) -> RunnerState:
    """Learner state and iteration count are the same on all devices and stored once; the rest
    belongs to one device and carries a leading device axis, split over `axis`."""
    return RunnerState(sac=P(), iteration=P(), **{name: P(axis) for name in PER_DEVICE_FIELDS})


def _device_axis(runner: RunnerState, add: bool) -> RunnerState:
    """Adds (or removes) the leading device axis of size 1 on a device's own fields."""
    shape = (lambda x: x[None]) if add else (lambda x: x[0])
    own = {name: jax.tree_util.tree_map(shape, getattr(runner, name))
           for name in PER_DEVICE_FIELDS}
    return runner.replace(**own)


def make_data_parallel_parts(config: SACConfig, mesh: Mesh) -> TrainParts:
    """`TrainParts` of one run of `config` spread over the mesh's single axis (see the module
    docstring); `config` holds the global sizes. `init(key)` and `chunk(runner)` are shard_mapped
    functions (jit them); the runner's `sac` and `iteration` are as in a one-device run, its
    `env`, `buffer`, `key`, `sums` and `outputs` have a leading device axis of size D
    (`data_parallel_metrics` turns the outputs into the run's metrics)."""
    axis = _axis(mesh)
    parts = make_train_parts(local_config(config, mesh.size, axis))
    specs = _runner_specs(axis)

    def init(key: jax.Array) -> RunnerState:
        index = jax.lax.axis_index(axis)
        own_key = jnp.where(index == 0, key, jax.random.fold_in(key, index))
        runner = parts.init(own_key).replace(sac=parts.init(key).sac)
        return _device_axis(runner, add=True)

    def chunk(runner: RunnerState) -> RunnerState:
        return _device_axis(parts.chunk(_device_axis(runner, add=False)), add=True)

    # check_vma=False: the learner state is replicated because every update averages over the
    # axis explicitly, which the varying-axes type check cannot see through.
    return TrainParts(
        init=jax.shard_map(init, mesh=mesh, in_specs=P(), out_specs=specs, check_vma=False),
        chunk=jax.shard_map(chunk, mesh=mesh, in_specs=(specs,), out_specs=specs, check_vma=False),
        chunk_iterations=parts.chunk_iterations, num_chunks=parts.num_chunks)


def data_parallel_metrics(outputs: Dict[str, jax.Array]) -> Dict[str, jax.Array]:
    """The run's metrics, as `make_train` reports them, from per-device outputs (D, num_evals):
    `env_steps` summed over devices; `eval_return` the mean over all devices' episodes (each
    evaluates `eval_episodes`); `train_return` the mean over devices of each device's mean
    training return (NaN where no device ended an episode); update metrics are equal on all
    devices (device 0's)."""
    returns = ("eval_return", "train_return")
    metrics = {name: jnp.nanmean(outputs[name], axis=0) for name in returns}
    metrics["env_steps"] = jnp.sum(outputs["env_steps"], axis=0)
    metrics.update({name: outputs[name][0] for name in METRIC_NAMES})
    return metrics


def make_data_parallel_train(config: SACConfig, mesh: Mesh) -> Callable:
    """`train(key) -> (runner, metrics)` as `sac_jax.train.make_train(config)` returns, the run
    spread over the mesh's axis (`make_data_parallel_parts`, `data_parallel_metrics`)."""
    parts = make_data_parallel_parts(config, mesh)

    def train(key: jax.Array):
        runner = jax.lax.scan(lambda r, _: (parts.chunk(r), None), parts.init(key), None,
                              length=parts.num_chunks)[0]
        return runner, data_parallel_metrics(runner.outputs)

    return train
