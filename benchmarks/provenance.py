"""Where a benchmark figure comes from: every script writes its results with the command that
produced them, the machine, the package versions and the date, to benchmarks/results/NAME.json."""

from __future__ import annotations

import datetime
import importlib.metadata
import json
import os
import platform
import sys

RESULTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")
PACKAGES = ("jax", "jaxlib", "flax", "optax", "mujoco", "mujoco-mjx", "brax", "distrax")


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def provenance() -> dict:
    """The command (as typed: `python -m benchmarks.x ...`), machine, versions and UTC date."""
    import jax

    versions = {}
    for name in PACKAGES:
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            versions[name] = None
    module = sys.modules["__main__"].__spec__
    program = (f"python -m {module.name}" if module is not None
               else f"python {os.path.relpath(sys.argv[0])}")
    return {"command": " ".join([program, *sys.argv[1:]]),
            "machine": {"cpu": _cpu_model(), "cores": os.cpu_count(),
                        "devices": [str(d) for d in jax.devices()],
                        "xla_flags": os.environ.get("XLA_FLAGS", "")},
            "python": platform.python_version(), "versions": versions,
            "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}


def write_result(name: str, result: dict, source: dict) -> str:
    """Writes {"provenance": source, "result": result} to benchmarks/results/NAME.json."""
    os.makedirs(RESULTS, exist_ok=True)
    path = os.path.join(RESULTS, f"{name}.json")
    with open(path, "w") as f:
        json.dump({"provenance": source, "result": result}, f, indent=1)
        f.write("\n")
    print(f"wrote {path}")
    return path
