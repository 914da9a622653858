"""Shared test setup: JAX's persistent compilation cache, so MJX programs compile once per
machine; the float64 comparisons of tests/parallel_checks.py, measured once per session for
test_parallel.py and test_train.py (one subprocess, whose compiled programs they share)."""

import pytest

from sac_jax.compilation_cache import enable_compilation_cache

enable_compilation_cache()


@pytest.fixture(scope="session")
def float64_checks():
    """The float64 comparisons of tests/parallel_checks.py (see its docstring)."""
    from tests.parallel_checks import run_parallel_checks

    return run_parallel_checks("updates", "seeds", "separate", "settings", "one_device",
                               x64=True)
