"""One process's `sac_jax.run_dir.state_template` of the `fast` preset's state (InvertedPendulum
in MJX) with both caches in DIRECTORY, for tests/test_program_cache.py. Prints a JSON object:
whether the state's constructor was traced, the shapes and dtypes, and how many shape files
the program cache holds.

    python -m tests.state_shapes_run DIRECTORY
"""

import json
import os
import sys

import jax

from sac_jax import run_dir, train
from sac_jax.compilation_cache import enable_compilation_cache, program_directory
from sac_jax.presets import PRESETS


def main(directory: str) -> None:
    enable_compilation_cache(directory)
    traced = []
    make = train.make_train_parts
    run_dir.make_train_parts = lambda *a, **k: traced.append(1) or make(*a, **k)
    state = run_dir.state_template(PRESETS["fast"], 2)
    shapes = [[list(x.shape), str(x.dtype)] for x in jax.tree_util.tree_leaves(state)]
    files = sum(name.endswith(".shapes") for name in os.listdir(program_directory()))
    print(json.dumps({"traced": bool(traced), "shapes": shapes, "files": files,
                      "warp": "warp" in sys.modules}))


if __name__ == "__main__":
    main(*sys.argv[1:])
