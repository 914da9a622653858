"""Command-line scripts (train, evaluate, render, sweep); `sac_jax.cli` holds what they share.

pip installs this directory as the package `sac_jax_scripts`, with console.py as the `sac-jax`
command (pyproject.toml); in a checkout it is `scripts`, and each script also runs as a file.
"""
