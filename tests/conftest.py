"""Shared test setup: JAX's persistent compilation cache, so MJX programs compile once per machine."""

from sac_jax.compilation_cache import enable_compilation_cache

enable_compilation_cache()
