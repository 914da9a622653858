"""Benchmarks: each writes benchmarks/results/NAME.json. They compile under the XLA flags that
scripts/train.py sets (`sac_jax.compilation_cache.sequential_cpu_scheduler`, set here, before any
benchmark starts JAX), so that a program timed in a benchmark's process is the script's."""

from sac_jax.compilation_cache import sequential_cpu_scheduler

sequential_cpu_scheduler()
