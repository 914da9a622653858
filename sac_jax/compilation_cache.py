"""JAX's persistent compilation cache: compiled programs are kept on disk between processes, and
in its `programs/` folder the traced programs of `sac_jax.program_cache`."""

from __future__ import annotations

import os
import tempfile
import warnings
from typing import Optional

import jax

DEFAULT_DIR = os.path.join(os.path.expanduser("~"), ".cache", "sac-jax", "jax")


def enable_compilation_cache(directory: Optional[str] = None) -> Optional[str]:
    """Turns the cache on in `directory` (default: $JAX_COMPILATION_CACHE_DIR or
    ~/.cache/sac-jax/jax), caching every compilation however short; returns the directory. A
    directory that cannot be created or written leaves the cache off, with one warning, and
    returns None: a run then compiles everything, as without the cache."""
    directory = directory or os.environ.get("JAX_COMPILATION_CACHE_DIR") or DEFAULT_DIR
    try:
        os.makedirs(directory, exist_ok=True)
        tempfile.TemporaryFile(dir=directory).close()
    except OSError as error:
        warnings.warn(f"compilation cache {directory}: not writable ({error.strerror}); "
                      "compiling without it", stacklevel=2)
        disable_compilation_cache()
        return None
    jax.config.update("jax_enable_compilation_cache", True)
    jax.config.update("jax_compilation_cache_dir", directory)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)
    return directory


def disable_compilation_cache() -> None:
    """Turns both caches off (`--no-cache`), even where $JAX_COMPILATION_CACHE_DIR, which JAX
    reads itself, names a directory."""
    jax.config.update("jax_enable_compilation_cache", False)


def use_compilation_cache(on: bool, directory: Optional[str] = None) -> Optional[str]:
    """A script's `--cache`/`--no-cache` (`--cache-dir`): `enable_compilation_cache(directory)`
    if `on`, else `disable_compilation_cache()`; returns the directory in use, or None."""
    if on:
        return enable_compilation_cache(directory)
    disable_compilation_cache()
    return None


def active_directory() -> Optional[str]:
    """The persistent compilation cache's directory; None while the cache is off."""
    directory = jax.config.jax_compilation_cache_dir
    if not directory or not jax.config.jax_enable_compilation_cache:
        return None
    return directory


def program_directory() -> Optional[str]:
    """Where `sac_jax.program_cache` keeps traced programs: `programs/` in the persistent
    compilation cache's directory; None while that cache is off."""
    directory = active_directory()
    return None if directory is None else os.path.join(directory, "programs")


MUJOCO_CPU_COMPILER_OPTIONS = {"xla_cpu_use_fusion_emitters": False,
                               "xla_backend_optimization_level": 1}
"""XLA options for compiling, on a CPU, the training programs of an environment that simulates
MuJoCo (`envs.Env.simulates_mujoco`). 2 CPU cores, `fast` preset (InvertedPendulum-v5):
XLA's older LLVM emitters compile the chunk in 16.1 s instead of 21.1 s and train its first
768 iterations in 2.2-2.3 s instead of 1.8-1.9 s, so a first run reaches its solved policy
about 4 s sooner; LLVM's optimisation level 1 (of 3; 2 is XLA's default) then takes a cold
`scripts/train.py` from 10.3-10.4 s to 8.8-9.0 s of compilation, and its training stays at
2.5-2.6 s either way (level 0: 5.4 s to compile the chunk instead of 8.3 s, but a 3.8x slower
run). Later runs read the compiled programs from the cache. For environments without MuJoCo
XLA's default is kept: with it rejax's Pendulum-v1 configuration compiles in 4.3 s instead of
2.9 s (older emitters), but trains 10,000 steps in 7.0 s instead of 8.8 s."""


SEQUENTIAL_CPU_SCHEDULER = "--xla_cpu_enable_concurrency_optimized_scheduler=false"
"""The XLA flag of `sequential_cpu_scheduler`."""


def sequential_cpu_scheduler() -> None:
    """Adds `SEQUENTIAL_CPU_SCHEDULER` to $XLA_FLAGS, unless the flag is there already.
    By default XLA's CPU compiler orders a program's kernels so that independent ones can run at
    once on its threads; SAC's kernels are small, and handing them between threads costs more
    than running them at once saves. rejax's Pendulum-v1 configuration (64 wide, batch 256,
    10k steps, 1 seed, `jax.jit(make_train(config))`) trained in 4.90-4.99 s against
    5.44-5.53 s, with the same returns bit for bit; `fast` in 10.5-10.8 s against 10.7-10.8 s,
    compiling as long (2 cores of a 2.6 GHz Intel Xeon, alternated processes, 2 each). On 2
    cores of a Zen 4 AMD EPYC it changed nothing beyond noise: rejax's configuration trained in
    a median 6.05 s (5.71-6.43) with it against 5.95 s (5.79-6.38) without (3 alternated
    processes each, 3 calls per process, 2026-12-05).
    XLA reads this option from its flags, not from a program's compiler options (given to
    `compile` it changed nothing), so it takes effect only before JAX starts its backends (the
    first array or device query); after that this does nothing, and $XLA_FLAGS stays as it
    was, as JAX's cache keys read it. Scripts call it; a library import does not."""
    from jax._src import xla_bridge  # no public way to ask whether the backends have started

    flags = os.environ.get("XLA_FLAGS", "")
    name = SEQUENTIAL_CPU_SCHEDULER.split("=")[0]
    if name in flags or xla_bridge.backends_are_initialized():
        return
    os.environ["XLA_FLAGS"] = f"{flags} {SEQUENTIAL_CPU_SCHEDULER}".strip()


def compiler_options(env) -> dict:
    """Options for `jax.stages.Lowered.compile` of a training program on `env` on the default
    backend. On a GPU, XLA's defaults: without Triton's matrix products (cuBLAS's instead), an
    H100 compiles `fast` about 2 s sooner, but trains it 2.09-2.20 s to solved against
    1.90-1.99 s, and rejax's Pendulum-v1 configuration with 256 seeds 9.2-9.8 s against
    5.3-5.6 s (BENCHMARKS.md, 2026-11-27)."""
    if jax.default_backend() == "cpu" and env.simulates_mujoco:
        return dict(MUJOCO_CPU_COMPILER_OPTIONS)
    return {}
