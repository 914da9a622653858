"""The `sac-jax` command: `sac-jax COMMAND [FLAGS]` runs scripts/COMMAND.py with its flags.

    sac-jax train --preset pendulum --out runs/pendulum      # python scripts/train.py ...
    sac-jax evaluate runs/pendulum --paired
    sac-jax render runs/pendulum --out swing.gif
    sac-jax sweep --set actor_lr=1e-3,3e-4 --seeds 2
    sac-jax --help                                           # the commands; COMMAND --help

pip installs this directory as the package `sac_jax_scripts` (pyproject.toml maps it; no
top-level `scripts` is installed), so the command works from `pip install .` and
`pip install -e .` alike. This module imports only the standard library until it has read the
command, then imports that one script: scripts/render.py must choose MuJoCo's OpenGL backend
(MUJOCO_GL) before mujoco is imported, and `sac_jax` and `envs` import mujoco. An unknown or
missing command ends with one line on stderr and exit 2.
"""

from __future__ import annotations

import importlib
import sys
from typing import Optional, Sequence

PROG = "sac-jax"
COMMANDS = {
    "train": "train SAC, all seeds in one compiled program",
    "evaluate": "evaluate a saved policy in our environment and in Gymnasium's",
    "render": "render an episode of a saved policy to a GIF or an MP4",
    "sweep": "sweep hyperparameters: a grid of settings x seeds",
}
"""Each command runs scripts/<command>.py; the text is its line in `sac-jax --help`."""


def usage() -> str:
    """The text of `sac-jax --help`: the commands and what each does."""
    width = max(map(len, COMMANDS))
    lines = [f"usage: {PROG} COMMAND [FLAGS]", "", "Soft Actor-Critic in JAX/Flax.", "",
             "commands:"]
    lines += [f"  {name:<{width}}  {summary}" for name, summary in COMMANDS.items()]
    lines += ["", f"{PROG} COMMAND --help lists the flags of COMMAND."]
    return "\n".join(lines)


def _script(name: str):
    """The module of the script `name`: a sibling of this one, in the package this module was
    imported from (`sac_jax_scripts` when installed, `scripts` in a checkout)."""
    return importlib.import_module(f"{__package__}.{name}" if __package__ else name)


def main(argv: Optional[Sequence[str]] = None) -> None:
    """Runs `sac-jax` on `argv` (default: sys.argv[1:]) and exits as the script does: the
    script sees sys.argv as [f"sac-jax {name}", *flags], just as when run as a file."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv and argv[0] in ("-h", "--help"):
        print(usage())
        sys.exit(0)
    choices = ", ".join(COMMANDS)
    if not argv:
        print(f"error: missing command: one of {choices} (see {PROG} --help)", file=sys.stderr)
        sys.exit(2)
    name, flags = argv[0], argv[1:]
    if name not in COMMANDS:
        print(f"error: unknown command {name!r}: must be one of {choices} (see {PROG} --help)",
              file=sys.stderr)
        sys.exit(2)
    saved = sys.argv
    sys.argv = [f"{PROG} {name}", *flags]
    try:
        script = _script(name)
        from sac_jax.cli import run_main  # only now: sac_jax imports mujoco

        run_main(script.main)
    finally:
        sys.argv = saved


if __name__ == "__main__":
    main()
