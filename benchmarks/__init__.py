"""Benchmarks: each writes benchmarks/results/NAME.json. They compile under the XLA flags that
scripts/train.py sets (`sac_jax.compilation_cache.sequential_cpu_scheduler`) and run, on a CPU,
on the runtime of its one-seed runs (one device of one thread,
`sac_jax.parallel.cpu_device_per_core(1)`), both set here, before any benchmark starts JAX, so
that a program timed in a benchmark's process is the script's. `PEER_ENVIRON` is the
environment as it was before, for peers' processes, which run as their users run them."""

import os

from sac_jax.compilation_cache import sequential_cpu_scheduler
from sac_jax.parallel import cpu_device_per_core

PEER_ENVIRON = dict(os.environ)
sequential_cpu_scheduler()
cpu_device_per_core(1)
