"""One process's use of `sac_jax.program_cache`, for tests/test_program_cache.py: with JAX's
persistent compilation cache in CACHE and the program cache in PROGRAMS, `cached_lower` of a
fixed donating step, compiled and called once; the step factors a matrix (on a CPU, a LAPACK
call, whose kernels a loaded executable finds only if this process set them up). Prints a JSON
object: the step's result, how many programs this process compiled or read from JAX's cache
(`jax.stages.Lowered.compile` calls), and the traced programs and executables PROGRAMS then
holds.

    python -m tests.executable_cache_run PROGRAMS CACHE
"""

import json
import os
import sys

import jax
import jax.numpy as jnp

from sac_jax.compilation_cache import enable_compilation_cache
from sac_jax.program_cache import cached_lower


def step(state):
    return {"x": jnp.sin(state["x"]) * 3.0 + jnp.arange(4.0), "n": state["n"] + 1,
            "c": jnp.diagonal(jnp.linalg.cholesky(jnp.diag(state["x"] + 1.0)))}


def main(programs: str, cache: str) -> None:
    enable_compilation_cache(cache)
    compiles = []
    compile = jax.stages.Lowered.compile

    def counted(self, *args, **kwargs):
        compiles.append(1)
        return compile(self, *args, **kwargs)

    jax.stages.Lowered.compile = counted
    state = {"x": jnp.arange(4.0), "n": jnp.int32(0), "c": jnp.zeros(4)}
    out = cached_lower(step, "step", [state], state, programs, donate_first=True).compile()(
        state)
    names = os.listdir(programs)
    print(json.dumps({"x": out["x"].tolist(), "n": int(out["n"]), "c": out["c"].tolist(),
                      "donated": state["x"].is_deleted(), "compiled": len(compiles),
                      "programs": sum(n.endswith(".jaxexport") for n in names),
                      "executables": sum(n.endswith(".xla") for n in names)}))


if __name__ == "__main__":
    main(*sys.argv[1:])
