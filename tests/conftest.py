"""Shared test setup: JAX's persistent compilation cache, so MJX programs compile once per
machine; JAX's backends started at once, so that the scripts' `main` called in this process
(which asks for a CPU device per core, `parallel.cpu_device_per_core`, before JAX starts) keeps
one device whichever test runs first; before that, the XLA flags the scripts set
(`compilation_cache.sequential_cpu_scheduler`), so that scripts run here and in subprocesses
compile alike and share JAX's cached programs; the float64 comparisons of
tests/parallel_checks.py, measured once per session for test_parallel.py and test_train.py
(one subprocess, whose compiled programs they share)."""

import jax
import pytest

from sac_jax.compilation_cache import enable_compilation_cache, sequential_cpu_scheduler

sequential_cpu_scheduler()
enable_compilation_cache()
jax.devices()


@pytest.fixture(scope="session")
def float64_checks():
    """The float64 comparisons of tests/parallel_checks.py (see its docstring)."""
    from tests.parallel_checks import run_parallel_checks

    return run_parallel_checks("updates", "seeds", "separate", "settings", "one_device",
                               x64=True)
