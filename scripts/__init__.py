"""Command-line scripts (train, evaluate, render); `sac_jax.cli` holds what they share."""
