"""Spreading training over devices: a `jax.sharding.Mesh` with one named axis, and programs
mapped with `jax.vmap` whose mapped axis is split over it by `NamedSharding` (XLA's partitioner
then compiles one program per device and the collectives between them).

Seeds over devices (axis "seeds"): the S independent runs of `jax.vmap(train)` are split into
D groups of S/D, one per device, by sharding the seed axis (`NamedSharding`); the program is
the same, and the devices exchange only one sum per iteration, whether an episode ended in any
seed (`envs.VectorEnv`'s `reset_axis`: all seeds reset together, one branch under `vmap`).

Data parallel (axis "data"): one run, spread over D devices as D shares vmapped with the axis's
name and split over the devices (`DATA_AXES`). Device d steps num_envs/D of the
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

import importlib.metadata
import importlib.util
import os
from typing import Callable, Dict, Optional, Sequence, Tuple

import jax
import jax.numpy as jnp
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

from envs._validate import is_positive_int
from sac_jax.config import SACConfig
from sac_jax.train import (EVAL_NAMES, METRIC_NAMES, SEED_AXES, RunnerState, TrainParts,
                           make_train_parts)

SEEDS = "seeds"
DATA = "data"
SHARDED_FIELDS = ("num_envs", "buffer_size", "batch_size", "learning_starts", "eval_every")
"""Config sizes a data-parallel run divides among its devices."""


def make_mesh(axis: str, devices: Optional[Sequence[jax.Device]] = None) -> Mesh:
    """A one-axis mesh named `axis` over `devices` (default: all devices of all processes)."""
    devices = jax.devices() if devices is None else list(devices)
    return Mesh(devices, (axis,))


def _axis(mesh: Mesh) -> str:
    """The name of the mesh's only axis."""
    if len(mesh.axis_names) != 1:
        raise ValueError(f"mesh axes {mesh.axis_names}: need a mesh with exactly one axis")
    return mesh.axis_names[0]


def _shardings(axes, mesh: Mesh):
    """For a tree of `jax.vmap` axes: leaves mapped on axis 0 split over the mesh's axis,
    unmapped (None) leaves whole on every device."""
    split, whole = NamedSharding(mesh, P(_axis(mesh))), NamedSharding(mesh, P())
    return jax.tree_util.tree_map(lambda axis: whole if axis is None else split, axes,
                                  is_leaf=lambda axis: axis is None)


# ---------------------------------------------------------------------------- seeds
def over_seeds(fn: Callable, mesh: Mesh, in_axes=0, out_axes=0, donate: bool = False
               ) -> Callable:
    """`jax.jit(jax.vmap(fn, in_axes, out_axes))` with every mapped (seeds) axis of the arguments
    and results split over the mesh's axis, and unmapped (None) parts, such as the counters of
    `sac_jax.train.SEED_AXES`, held whole on every device: each device runs `jax.vmap(fn)` on
    its S/D seeds. S must be a multiple of the number of devices D. `donate` donates the
    (single) argument's buffers.

    The split is stated as `NamedSharding`s of the inputs and outputs and left to XLA's
    partitioner (the seeds share one thing: whether any seed's episode ended, a sum over the
    axis SEEDS that `sac_jax.train.make_train`'s `seed_axis` asks for). `jax.shard_map` would
    say the same thing, but XLA's GPU compiler of jax 0.11.2 crashes on the shard_mapped
    training program (BENCHMARKS.md), while this form compiles and runs on 2 GPUs."""
    return jax.jit(jax.vmap(fn, in_axes, out_axes, axis_name=SEEDS),
                   donate_argnums=(0,) if donate else (), **_placement(in_axes, out_axes, mesh))


def _placement(in_axes, out_axes, mesh: Mesh) -> dict:
    """`jax.jit`'s in_shardings and out_shardings of `over_seeds`."""
    return dict(in_shardings=_shardings(in_axes, mesh), out_shardings=_shardings(out_axes, mesh))


def over_seed_axis(fn: Callable, seeds: int, in_axes=0, out_axes=0) -> Callable:
    """`jax.vmap(fn, in_axes, out_axes)` over `seeds` seeds (axis name SEEDS). For one seed, `fn`
    itself between taking seed 0 of the mapped (axis 0) parts of the arguments and putting the
    seed axis back on the results: the same values up to float32 rounding (a vmap of size 1
    batches every operation, and XLA rounds a batched product differently), and half the
    tracing of the `fast` chunk on a CPU (5 s instead of 10 s; BENCHMARKS.md)."""
    if seeds != 1:
        return jax.vmap(fn, in_axes, out_axes, axis_name=SEEDS)

    def mapped(f, axes, tree):
        return jax.tree_util.tree_map(
            lambda axis, part: part if axis is None else jax.tree_util.tree_map(f, part),
            axes, tree, is_leaf=lambda axis: axis is None)

    def one_seed(*args):
        axes = in_axes if isinstance(in_axes, (tuple, list)) else (in_axes,) * len(args)
        result = fn(*mapped(lambda x: x[0], tuple(axes), args))
        return mapped(lambda x: x[None], out_axes, result)

    return one_seed


def seed_axis(seeds: int) -> Optional[str]:
    """The `seed_axis` of `sac_jax.train.make_train(config, seed_axis=...)` for a program that
    `seeds_program` maps over `seeds` seeds: SEEDS, or None for one seed, which
    `over_seed_axis` runs unmapped."""
    return SEEDS if seeds > 1 else None


def seed_devices(seeds: int, devices: Optional[Sequence[jax.Device]] = None) -> list:
    """The devices (default: the local ones) that `seeds` seeds are split over: the first k,
    k the largest number of them that divides `seeds` (one device for one seed)."""
    devices = jax.local_devices() if devices is None else list(devices)
    return devices[:max(k for k in range(1, len(devices) + 1) if seeds % k == 0)]


def seed_mapping(fn: Callable, seeds: int, in_axes=0, out_axes=0) -> Tuple[Callable, dict]:
    """(`fn` mapped over `seeds` seeds, `jax.jit`'s keyword arguments that place it): on
    `seed_devices(seeds)` when they are several, `jax.vmap(fn)` with the `in_shardings` and
    `out_shardings` of `over_seeds`; on one device, `over_seed_axis` and no placement."""
    devices = seed_devices(seeds)
    if len(devices) == 1:
        return over_seed_axis(fn, seeds, in_axes, out_axes), {}
    return (jax.vmap(fn, in_axes, out_axes, axis_name=SEEDS),
            _placement(in_axes, out_axes, make_mesh(SEEDS, devices)))


def seeds_program(fn: Callable, seeds: int, in_axes=0, out_axes=0, donate: bool = False
                  ) -> Callable:
    """`jax.jit` of `seed_mapping`: `over_seeds` on `seed_devices(seeds)` when they are
    several, otherwise `over_seed_axis` on one device. `donate` donates the first argument."""
    mapped, placement = seed_mapping(fn, seeds, in_axes, out_axes)
    return jax.jit(mapped, donate_argnums=(0,) if donate else (), **placement)


def cpu_device_per_core(seeds: Optional[int] = None) -> None:
    """Makes JAX's CPU backend one device per CPU core this process may use
    (`jax_num_cpu_devices`), so that `seeds_program` runs the seed groups of a CPU run on the
    cores at once; for a run of `seeds` seeds, only as many as `seed_devices` will use (the
    largest count up to the cores that divides `seeds`). XLA's CPU runtime keeps SAC's small
    layers mostly on one thread: 16 seeds of rejax's Pendulum-v1 configuration (64 wide, batch
    256, 10k steps) trained in 55.8 s on two CPU devices against 95.9 s for the same program on
    one (2 cores, BENCHMARKS.md "rejax"). A run on one device also gets a runtime of one thread
    (`single_thread_cpu_runtime`): 3 seeds on 2 cores, which `seed_devices` keeps on one
    device, trained in 16.3-16.9 s against 21.3-21.5 s on one of 2 devices (2 alternated
    warm `scripts/train.py` runs each, 2026-12-07).
    Takes effect only before JAX starts its backends (the first array or device query); it
    leaves a count set already by $JAX_NUM_CPU_DEVICES or XLA_FLAGS'
    --xla_force_host_platform_device_count. Scripts call it; a library import does not."""
    if (jax.config.jax_num_cpu_devices != -1
            or "xla_force_host_platform_device_count" in os.environ.get("XLA_FLAGS", "")):
        return
    cores = (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
             else os.cpu_count() or 1)
    count = cores if seeds is None else len(seed_devices(seeds, range(cores)))
    try:
        jax.config.update("jax_num_cpu_devices", count)
    except RuntimeError:  # the backends have started: keep their devices
        return
    if count == 1:
        single_thread_cpu_runtime()


def single_thread_cpu_runtime() -> None:
    """Sizes the thread pool of JAX's CPU runtime to one thread ($PJRT_NPROC=1, which XLA reads
    when JAX starts its backends), unless $PJRT_NPROC is set, and only where JAX uses its CPU
    backend alone ($PJRT_NPROC also sizes a GPU client's host thread pool). On one CPU device
    XLA otherwise hands SAC's small kernels between threads, at a cost larger than what running
    them at once saves. 2 cores of a 2.6 GHz Intel Xeon, 2026-12-07, alternated processes, the
    same returns bit for bit: warm `scripts/train.py` runs of rejax's Pendulum-v1 configuration
    (1 seed, 10k steps) trained in 4.44-4.65 s against 5.40-6.22 s on one device of XLA's
    default 2 threads and 5.78-6.19 s on one of 2 devices (the scripts' earlier default), its
    jitted program in 4.48-4.71 s against 5.72-5.78 s; a cold README command compiled as long
    (9.30 s against 9.24-9.37 s) and was solved after 3.58-3.82 s of training against
    3.90-3.94 s. On several devices XLA keeps a thread per device and this changes nothing (16
    seeds on 2 devices: 45.7-45.8 s against 44.7-45.5 s)."""
    if "PJRT_NPROC" not in os.environ and _only_cpu():
        os.environ["PJRT_NPROC"] = "1"


def _only_cpu() -> bool:
    """Whether JAX will start its CPU backend alone: $JAX_PLATFORMS names only "cpu", or it
    is unset and no accelerator plugin (the `jax_plugins` namespace or entry points) nor
    libtpu is installed."""
    if jax.config.jax_platforms:
        return jax.config.jax_platforms.strip() == "cpu"
    return (importlib.util.find_spec("jax_plugins") is None
            and not importlib.metadata.entry_points(group="jax_plugins")
            and importlib.util.find_spec("libtpu") is None)


# ---------------------------------------------------------------------------- data parallel
def local_config(config: SACConfig, num_devices: int, axis: str = DATA) -> SACConfig:
    """One device's share of a data-parallel run of `config` over `num_devices` devices: the
    `SHARDED_FIELDS` divided by D (each must be a multiple of D), the same number of iterations
    and evaluations, and gradients averaged over `axis`."""
    if not is_positive_int(num_devices):
        raise ValueError(f"num_devices={num_devices!r}: must be a positive integer")
    for field in SHARDED_FIELDS:
        value = getattr(config, field)
        if value % num_devices:
            raise ValueError(f"SACConfig.{field}={value}: must be a multiple of the "
                             f"{num_devices} devices of the data-parallel run")
    shares = {field: getattr(config, field) // num_devices for field in SHARDED_FIELDS}
    total = shares["learning_starts"] + config.num_evals * shares["eval_every"]
    return config.replace(**shares, total_steps=total, data_parallel_axis=axis)


DATA_AXES = SEED_AXES.replace(sac=None, delivered=None, stopped=None, non_finite=None,
                               hyperparams=None)
"""`jax.vmap` axes of a data-parallel run's state over its D device shares: the learner state
(every update averages over the axis, so all shares hold the same), the delivered actor and the
stop flag (selected on evaluation returns averaged over the axis), the traced hyperparameters
and the counters are held once; environments, replay buffer data, keys, sums and outputs have
a leading axis D."""


def _constrain(tree, axes, mesh: Mesh):
    """`tree`, mapped on `axes`, constrained to `_shardings(axes, mesh)`."""
    return jax.lax.with_sharding_constraint(tree, _shardings(axes, mesh))


def make_data_parallel_parts(config: SACConfig, mesh: Mesh) -> TrainParts:
    """`TrainParts` of one run of `config` spread over the mesh's single axis (see the module
    docstring); `config` holds the global sizes. `init(key, hyperparams=None)`, `advance` and
    `evaluate` map the one-device program over the D shares with `jax.vmap` (axis named like the
    mesh's, so the updates' `pmean` averages over it) and state the split of the shares over the
    devices as sharding constraints, which XLA's partitioner turns into per-device programs and an
    all-reduce per update (jit them). The runner's `sac` and counters are as in a one-device run;
    its `env`, `buffer.data`, `key`, `sums` and `outputs` have a leading axis D
    (`data_parallel_metrics` turns the outputs into the run's metrics)."""
    axis = _axis(mesh)
    # environments reset on the iterations where an episode ended on any device (`VectorEnv`)
    parts = make_train_parts(local_config(config, mesh.size, axis), seed_axis=axis)

    def init(key: jax.Array, hyperparams=None) -> RunnerState:
        shared = parts.init(key, hyperparams)

        def share(index):
            own_key = jnp.where(index == 0, key, jax.random.fold_in(key, index))
            return parts.init(own_key, hyperparams).replace(sac=shared.sac,
                                                            delivered=shared.delivered)

        runner = jax.vmap(share, out_axes=DATA_AXES, axis_name=axis)(jnp.arange(mesh.size))
        return _constrain(runner, DATA_AXES, mesh)

    def shared(part: Callable) -> Callable:
        def run(runner: RunnerState, *args) -> RunnerState:
            runner = jax.vmap(lambda r: part(r, *args), in_axes=(DATA_AXES,),
                              out_axes=DATA_AXES, axis_name=axis)(
                _constrain(runner, DATA_AXES, mesh))
            return _constrain(runner, DATA_AXES, mesh)
        return run

    return TrainParts(init=init, advance=shared(parts.advance), evaluate=shared(parts.evaluate),
                      num_iterations=parts.num_iterations, num_chunks=parts.num_chunks)


def data_parallel_metrics(outputs: Dict[str, jax.Array]) -> Dict[str, jax.Array]:
    """The run's metrics, as `make_train` reports them, from per-device outputs (D, num_evals):
    `env_steps` summed over devices; `eval_return` the mean over all devices' episodes (each
    evaluates `eval_episodes`); `train_return` the mean over devices of each device's mean
    training return (NaN where no device ended an episode); update metrics are equal on all
    devices (device 0's), as are the selection's returns, averaged over all devices' episodes
    inside the program (`confirm_return`, `kept_return`, `delivered_return`), and `stopped`."""
    returns = ("eval_return", "train_return")
    metrics = {name: jnp.nanmean(outputs[name], axis=0) for name in returns}
    metrics["env_steps"] = jnp.sum(outputs["env_steps"], axis=0)
    metrics.update({name: outputs[name][0]
                    for name in METRIC_NAMES + EVAL_NAMES if name not in returns})
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
