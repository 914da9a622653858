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
        return None
    jax.config.update("jax_compilation_cache_dir", directory)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)
    return directory


def program_directory() -> Optional[str]:
    """Where `sac_jax.program_cache` keeps traced programs: `programs/` in the persistent
    compilation cache's directory; None while that cache is off."""
    directory = jax.config.jax_compilation_cache_dir
    if not directory or not jax.config.jax_enable_compilation_cache:
        return None
    return os.path.join(directory, "programs")


CPU_COMPILER_OPTIONS = {"xla_cpu_use_fusion_emitters": False}
"""XLA options for compiling the training program on a CPU: XLA's older LLVM emitters compile the
MJX training chunk in about 18 s instead of 27 s and run it as fast (BENCHMARKS.md)."""


def compiler_options() -> dict:
    """Options for `jax.stages.Lowered.compile` on the default backend."""
    return dict(CPU_COMPILER_OPTIONS) if jax.default_backend() == "cpu" else {}
