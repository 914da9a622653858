"""Where a preset's compiled programs come from: their operations counted by source.

Lowers the programs `scripts/train.py` compiles for a preset (`init`, `advance` and `evaluate`
of `sac_jax.train.make_train_parts`, one seed) to StableHLO with locations, and counts each
operation once, under the innermost Python frame it was traced from (its file, and the
package: the folder under site-packages, or the repository's top folder; "(none)" where the
operation has no frame, as for some of JAX's own lowerings, or only this script's call). This
is the program before XLA optimises it, so a count measures what XLA's passes work through,
not the kernels that run. Writes benchmarks/results/program_sources-PRESET-KIND.json
(command, machine, versions, date).

    python -m benchmarks.program_sources --preset fast
"""

from __future__ import annotations

import argparse
import collections
import os
import re
from typing import Dict

import jax

import sac_jax
from benchmarks.provenance import provenance, result_name, write_result
from sac_jax.run import Chunk
from sac_jax.train import make_train_parts

_ALIAS = re.compile(r"^#(loc\d+) = loc\((.*)\)$", re.M)
_OP = re.compile(r'= "?(?:stablehlo|chlo)\.\w+.*loc\(#(loc\d+)\)\s*$')
_FILE = re.compile(r'"([^"]+\.py)":\d+')
_REF = re.compile(r"#(loc\d+)")
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def innermost_file(aliases: Dict[str, str], ref: str, depth: int = 0) -> str:
    """The first Python file of location `ref`: a callsite names the callee before the caller,
    so this is the innermost frame; "?" where there is none."""
    text = aliases.get(ref, "")
    found = _FILE.search(text)
    if found:
        return found.group(1)
    for inner in _REF.findall(text) if depth < 50 else ():
        name = innermost_file(aliases, inner, depth + 1)
        if name != "?":
            return name
    return "?"


def package(path: str) -> str:
    """The folder under site-packages, or the repository's top folder; "(none)" for no frame
    of the traced code."""
    if path in ("?", os.path.abspath(__file__)):
        return "(none)"
    if "site-packages/" in path:
        return path.split("site-packages/", 1)[1].split("/", 1)[0]
    if path.startswith(ROOT + os.sep):
        return os.path.relpath(path, ROOT).split(os.sep, 1)[0]
    return os.path.basename(path)


def count_sources(stablehlo: str) -> Dict[str, collections.Counter]:
    """{"files": Counter, "packages": Counter} of the operations in `stablehlo` (text with
    locations) by their innermost file."""
    aliases = dict(_ALIAS.findall(stablehlo))
    files = collections.Counter()
    for line in stablehlo.splitlines():
        op = _OP.search(line)
        if op:
            files[innermost_file(aliases, op.group(1))] += 1
    packages = collections.Counter()
    for path, n in files.items():
        packages[package(path)] += n
    return {"files": files, "packages": packages}


def short(path: str) -> str:
    """`path` under site-packages or the repository; "(none)" as in `package`."""
    if package(path) == "(none)":
        return "(none)"
    if "site-packages/" in path:
        return path.split("site-packages/", 1)[1]
    return os.path.relpath(path, ROOT) if path.startswith(ROOT + os.sep) else path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--preset", default=sac_jax.DEFAULT_PRESET, choices=sorted(sac_jax.PRESETS))
    parser.add_argument("--top", type=int, default=12, help="files listed per program")
    args = parser.parse_args()
    source = provenance()
    parts = make_train_parts(sac_jax.PRESETS[args.preset])
    state = jax.eval_shape(parts.init, jax.random.key(0))
    programs = {"init": (parts.init, jax.random.key(0)), "advance": (parts.advance, state),
                "evaluate": (parts.evaluate, Chunk.evaluated(state))}
    result = {"preset": args.preset, "programs": {}}
    for name, (function, argument) in programs.items():
        counts = count_sources(jax.jit(function).lower(argument).as_text(debug_info=True))
        files = collections.Counter()
        for path, n in counts["files"].items():
            files[short(path)] += n
        total = sum(files.values())
        result["programs"][name] = {
            "operations": total, "packages": dict(counts["packages"].most_common()),
            "files": dict(files.most_common(args.top))}
        print(f"{name}: {total} operations; by package {dict(counts['packages'].most_common())}")
    write_result(result_name(f"program_sources-{args.preset}"), result, source)


if __name__ == "__main__":
    main()
