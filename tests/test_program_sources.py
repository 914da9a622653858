"""benchmarks/program_sources.py: every operation of a lowered program is counted once, under
the innermost frame it was traced from (a library function's operations under the library's
file, not its caller's)."""

from __future__ import annotations

import os

import jax
import jax.numpy as jnp

from benchmarks import program_sources
from sac_jax import losses


def traced(q, target):
    scaled = jnp.sin(q) * 3.0
    return losses.critic_loss(scaled, target) + 1.0


def test_operations_are_counted_under_their_innermost_file():
    x = jnp.ones((2, 4))
    text = jax.jit(traced).lower(x, x).as_text(debug_info=True)
    counts = program_sources.count_sources(text)
    files = {program_sources.short(path): n for path, n in counts["files"].items()}
    here = os.path.relpath(__file__, program_sources.ROOT)
    assert files[here] >= 3  # sin, multiply, add
    assert files["sac_jax/losses.py"] >= 2  # the loss's own arithmetic
    operations = sum(1 for line in text.splitlines() if program_sources._OP.search(line))
    assert sum(counts["files"].values()) == operations == sum(counts["packages"].values())
    assert counts["packages"]["tests"] == files[here]
    assert counts["packages"]["sac_jax"] == files["sac_jax/losses.py"]
