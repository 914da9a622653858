"""Runs a measuring script in a fresh Python process (for settings that must precede JAX's
import: x64, forced host devices) and returns the JSON object of its last output line."""

import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run_json(args, **env_vars) -> dict:
    """`python ARGS...` from the repository root with `env_vars` added to the environment; fails
    the calling test with the script's stderr if it exits non-zero. XLA_FLAGS given here are
    appended to the caller's, not put in their place, so flags the suite runs under (such as
    `--xla_cpu_max_isa=SSE4_2`, emulating a CPU with fewer vector extensions) reach the
    subprocess too; a variable given None is unset there."""
    env = dict(os.environ, **{k: v for k, v in env_vars.items() if v is not None})
    for name in [k for k, v in env_vars.items() if v is None]:
        env.pop(name, None)
    if "XLA_FLAGS" in env_vars:
        env["XLA_FLAGS"] = " ".join(filter(None, [os.environ.get("XLA_FLAGS"),
                                                  env_vars["XLA_FLAGS"]]))
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [ROOT, env.get("PYTHONPATH")]))
    proc = subprocess.run([sys.executable, *args], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=1200)
    assert proc.returncode == 0, proc.stderr[-4000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])
