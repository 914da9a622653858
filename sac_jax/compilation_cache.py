"""JAX's persistent compilation cache: compiled programs are kept on disk between processes."""

from __future__ import annotations

import os
from typing import Optional

import jax

DEFAULT_DIR = os.path.join(os.path.expanduser("~"), ".cache", "sac-jax", "jax")


def enable_compilation_cache(directory: Optional[str] = None) -> str:
    """Turns the cache on in `directory` (default: $JAX_COMPILATION_CACHE_DIR or
    ~/.cache/sac-jax/jax), caching every compilation however short; returns the directory."""
    directory = directory or os.environ.get("JAX_COMPILATION_CACHE_DIR") or DEFAULT_DIR
    os.makedirs(directory, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", directory)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)
    return directory
