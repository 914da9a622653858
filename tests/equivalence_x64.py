"""The equivalence measurements in float64 (JAX x64, torch double), printed as one JSON object
{family: {error name: value}} on the last line of stdout.

Run as `JAX_ENABLE_X64=1 python -m tests.equivalence_x64 [family ...]` (test_equivalence_x64.py
does so in a subprocess, so x64 never reaches the other tests' process).
"""

from __future__ import annotations

import json
import os
import sys


def main(families):
    if os.environ.get("JAX_ENABLE_X64", "").lower() not in ("1", "true"):
        raise SystemExit("set JAX_ENABLE_X64=1")
    import jax

    from sac_jax.compilation_cache import enable_compilation_cache
    from tests.equivalence_harness import FAMILIES, measure

    assert jax.config.jax_enable_x64
    enable_compilation_cache()
    results = {f: measure(f, "float64") for f in (families or list(FAMILIES))}
    print(json.dumps(results))


if __name__ == "__main__":
    main(sys.argv[1:])
