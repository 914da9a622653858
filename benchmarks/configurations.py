"""The configurations a benchmark can be asked for by name: every preset (`sac_jax.PRESETS`)
and "rejax", rejax's tuned Pendulum-v1 SAC in our terms (`benchmarks.rejax_peer.CONFIG`)."""

from __future__ import annotations

from sac_jax.config import SACConfig
from sac_jax.presets import PRESETS

NAMES = tuple(sorted(PRESETS)) + ("rejax",)


def configuration(name: str) -> SACConfig:
    """The SACConfig named `name` (one of `NAMES`)."""
    if name == "rejax":
        from benchmarks.rejax_peer import CONFIG  # imports JAX's programs: only when asked
        return CONFIG
    return PRESETS[name]
