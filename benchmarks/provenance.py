"""Where a benchmark figure comes from: every script writes its results with the command that
produced them, the machine, the package versions and the date, to benchmarks/results/NAME.json
(or to $SAC_JAX_RESULTS_DIR/NAME.json where that is set: a trial run, or benchmarks/gpu.sh,
which copies them into the device tool's $OUT)."""

from __future__ import annotations

import datetime
import importlib.metadata
import json
import os
import platform
import re
import shlex
import subprocess
import sys

RESULTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")
PACKAGES = ("jax", "jaxlib", "ml_dtypes", "flax", "optax", "mujoco", "mujoco-mjx", "brax",
            "distrax", "torch", "gymnasium", "playground", "warp-lang")


def _cpuinfo() -> dict:
    """The first processor's fields in /proc/cpuinfo ({} where there is none)."""
    fields = {}
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if not line.strip():
                    break
                name, _, value = line.partition(":")
                fields[name.strip()] = value.strip()
    except OSError:
        pass
    return fields


def _cpu() -> dict:
    """The CPU: its model name, its family/model/stepping and clock (VMs often name every Xeon
    alike), and which of the vector extensions that set XLA's float32 rounding it has (as
    .ci/run prints)."""
    info = _cpuinfo()
    flags = set(info.get("flags", "").split())
    return {"cpu": info.get("model name") or platform.processor() or platform.machine(),
            "cpu_id": " ".join(f"{k} {info[k]}" for k in ("cpu family", "model", "stepping")
                               if k in info),
            "mhz": round(float(info["cpu MHz"])) if "cpu MHz" in info else None,
            "vector_extensions": [e for e in ("avx512f", "avx2", "fma", "sse4_2") if e in flags]}


def machine_kind(all_devices: bool = False) -> str:
    """A short name of the machine a figure is measured on, for its results file's name: "cpu",
    or the accelerator's model ("h100" from "NVIDIA H100 80GB HBM3"); with `all_devices`,
    prefixed by their count where there are several ("2xh200")."""
    import jax

    devices = jax.devices()
    if devices[0].platform == "cpu":
        return "cpu"
    kind = devices[0].device_kind
    model = re.search(r"\b([A-Za-z]+\d+)\b", kind)
    name = (model.group(1) if model else re.sub(r"\W+", "", kind)).lower()
    return f"{len(devices)}x{name}" if all_devices and len(devices) > 1 else name


def result_name(base: str, all_devices: bool = False) -> str:
    """`base`-KIND (`machine_kind`): "seed_scaling-h100", "update_throughput-cpu"."""
    return f"{base}-{machine_kind(all_devices)}"


def _commit() -> dict:
    """The sac-jax commit measured, and whether the tree had changes beside it (None where
    this is no git checkout, as on a device machine's copy of the tree)."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

    def git(*args):
        return subprocess.run(["git", "-C", root, *args], capture_output=True, text=True,
                              check=True).stdout.strip()
    try:
        return {"commit": git("rev-parse", "HEAD"),
                "changed": bool(git("status", "--porcelain", "--untracked-files=no"))}
    except (OSError, subprocess.CalledProcessError):
        return {"commit": None, "changed": None}


def provenance() -> dict:
    """The command (as typed: `python -m benchmarks.x ...`, quoted to paste into a shell), the
    sac-jax commit, machine, versions and UTC date."""
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
    source = {"command": f"{program} {shlex.join(sys.argv[1:])}".rstrip(), **_commit()}
    if os.environ.get("SAC_JAX_BENCHMARK_VIA"):  # benchmarks/gpu.sh's own command line
        source["via"] = os.environ["SAC_JAX_BENCHMARK_VIA"]
    return {**source,
            "machine": {**_cpu(), "cores": os.cpu_count(),
                        "devices": [str(d) for d in jax.devices()],
                        "device_kind": jax.devices()[0].device_kind,
                        "xla_flags": os.environ.get("XLA_FLAGS", "")},
            "python": platform.python_version(), "versions": versions,
            "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}


def write_result(name: str, result: dict, source: dict) -> str:
    """Writes {"provenance": source, "result": result} to benchmarks/results/NAME.json, or to
    $SAC_JAX_RESULTS_DIR/NAME.json where that is set."""
    directory = os.environ.get("SAC_JAX_RESULTS_DIR") or RESULTS
    os.makedirs(directory, exist_ok=True)
    path = os.path.join(directory, f"{name}.json")
    with open(path, "w") as f:
        json.dump({"provenance": source, "result": result}, f, indent=1)
        f.write("\n")
    print(f"wrote {path}")
    return path
