"""Traced programs kept on disk, so a second process neither traces nor compiles.

JAX's persistent compilation cache keeps compiled executables, but finding one still needs the
program traced in Python first, and tracing the MJX training chunk takes about 10 s on a CPU.
`cached_lower` keeps the traced program as well: the lowered StableHLO of `fn` at the given
argument shapes, as a function of the arguments' flat leaves, serialized by `jax.export`, in a
file named by a hash of everything the trace depends on:
    what the caller names (e.g. the configuration and the number of seeds),
    the arguments' leaves (their paths in the tree, shapes and dtypes) and the platform,
    JAX's settings that change a trace (`TRACE_SETTINGS`: x64, matmul precision, PRNG),
    the versions of Python, jax, jaxlib, flax, optax, distrax, mujoco and mujoco-mjx,
    the source of every module of `sac_jax` and `envs` (and the environments' assets).
A later process reads the file, compiles the deserialized program (`Exported.call` under
`jax.jit`; the persistent compilation cache then supplies the executable) and rebuilds the
result's tree from the structure the caller states. A program `jax.export` cannot serialize
(custom calls without its compatibility guarantee, such as MuJoCo Warp's, or host callbacks) is
lowered afresh in every process, without a file. Each file starts with MAGIC and the SHA-256
of the serialized program: a file whose bytes do not match (damaged on disk) is traced again
and replaced, with one warning; one that cannot be read otherwise (e.g. from an incompatible
jax) is traced again silently. Files are written under a temporary name and renamed.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import os
import platform
import sys
import warnings
from typing import Any, Callable, Optional, Sequence

import jax
from jax import export

from sac_jax.whole_file import write_file

PACKAGES = ("jax", "jaxlib", "flax", "optax", "distrax", "mujoco", "mujoco-mjx", "brax",
            "playground")
"""Installed packages whose code (and, for `brax/` and `playground/` tasks, models) the traced
programs contain."""
SOURCE_PACKAGES = ("sac_jax", "envs")
"""Packages whose source files (and assets) are hashed into every key."""
TRACE_SETTINGS = ("jax_enable_x64", "jax_default_matmul_precision", "jax_threefry_partitionable",
                  "jax_default_prng_impl", "jax_numpy_dtype_promotion", "jax_numpy_rank_promotion")
"""JAX settings that change what a trace produces, read as they stand (a context manager's
included) into every key."""


@functools.lru_cache(maxsize=1)
def _code_fingerprint() -> str:
    """Hash of the Python and package versions and of the source files of SOURCE_PACKAGES."""
    digest = hashlib.sha256(sys.version.encode())
    for name in PACKAGES:
        try:
            version = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:  # e.g. no MuJoCo for Pendulum-v1 alone
            version = "absent"
        digest.update(f"{name}=={version}".encode())
    for package in SOURCE_PACKAGES:
        root = os.path.dirname(sys.modules[package].__file__)
        for folder, dirs, files in sorted(os.walk(root)):
            dirs[:] = sorted(d for d in dirs if d != "__pycache__")
            for name in sorted(files):
                if name.endswith((".py", ".xml")):
                    path = os.path.join(folder, name)
                    digest.update(os.path.relpath(path, root).encode())
                    with open(path, "rb") as f:
                        digest.update(f.read())
    return digest.hexdigest()


def program_file(name: str, args: Sequence[Any]) -> str:
    """The file name of the traced program `name` (any string saying what the caller built,
    e.g. a repr of the configuration) at arguments `args` (arrays or ShapeDtypeStructs)."""
    leaves = [(jax.tree_util.keystr(path), tuple(x.shape), str(x.dtype))
              for path, x in jax.tree_util.tree_flatten_with_path(list(args))[0]]
    digest = hashlib.sha256()
    settings = repr([(s, getattr(jax.config, s, None)) for s in TRACE_SETTINGS])
    for part in (name, repr(leaves), jax.default_backend(), platform.machine(), settings,
                 _code_fingerprint()):
        digest.update(part.encode())
        digest.update(b"\0")
    return digest.hexdigest()[:32] + ".jaxexport"


MAGIC = b"sac-jax program 1\n"
"""The first bytes of a file of this cache, before the SHA-256 of the rest."""


def _read(path: str) -> Optional[export.Exported]:
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError:  # missing or unreadable: trace again
        return None
    digest, payload = data[len(MAGIC):len(MAGIC) + 32], data[len(MAGIC) + 32:]
    if not data.startswith(MAGIC) or hashlib.sha256(payload).digest() != digest:
        warnings.warn(f"cached program {path} is damaged (checksum mismatch); tracing it "
                      "again", stacklevel=3)
        return None
    try:
        return export.deserialize(bytearray(payload))
    except Exception:  # from an incompatible jax: trace again
        return None


def _write(path: str, exported: export.Exported) -> None:
    os.makedirs(os.path.dirname(path), exist_ok=True)
    payload = bytes(exported.serialize())
    write_file(path, MAGIC + hashlib.sha256(payload).digest() + payload)


def cached_lower(fn: Callable, name: str, args: Sequence[Any], result: Any, directory: str,
                 donate_first: bool = False, in_shardings: Optional[Sequence[Any]] = None,
                 out_shardings: Any = None) -> "CachedLowered":
    """`fn` lowered for arguments shaped like `args`, its traced program read from `directory`
    if an earlier process left it there, else traced now and stored there. `result` has the
    tree structure of what `fn` returns (e.g. the first argument, for a step function);
    `donate_first` donates the first argument's buffers; `in_shardings` (one tree per argument)
    and `out_shardings` (one tree), prefixes of `args` and `result` as `jax.jit`'s, place the
    program on several devices (they are part of the file's key). As `jax.jit(fn).lower`, this
    part holds Python's lock and `compile` does not: a thread can compile one program while the
    caller traces the next."""
    avals = jax.tree_util.tree_map(lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype), list(args))
    leaves, treedef = jax.tree_util.tree_flatten(avals)
    result_tree = jax.tree_util.tree_structure(result)
    placement = {} if in_shardings is None else dict(
        in_shardings=tuple(_per_leaf(list(in_shardings), avals)),
        out_shardings=_per_leaf(out_shardings, result))

    def flat(*leaves):
        out, out_tree = jax.tree_util.tree_flatten(fn(*jax.tree_util.tree_unflatten(treedef,
                                                                                      leaves)))
        if out_tree != result_tree:
            raise ValueError(f"{name}: returns {out_tree}, stated {result_tree}")
        return out

    path = os.path.join(directory, program_file(f"{name} {placement!r}", avals))
    donated = tuple(range(len(jax.tree_util.tree_leaves(avals[0])))) if donate_first else ()
    exported = _read(path)
    if exported is None:
        try:
            exported = export.export(jax.jit(flat, **placement))(*leaves)
        except (ValueError, NotImplementedError) as error:
            if not _unserializable(error):
                raise
            return CachedLowered(jax.jit(flat, donate_argnums=donated, **placement).lower(
                *leaves), result_tree)
        try:
            _write(path, exported)
        except OSError as error:  # a full or read-only disk: the next process traces again
            warnings.warn(f"cached program {path}: not written ({error.strerror})",
                          stacklevel=2)
    return CachedLowered(jax.jit(exported.call, donate_argnums=donated, **placement).lower(
        *leaves), result_tree)


def _unserializable(error: Exception) -> bool:
    """Whether `jax.export` refused a program for what it holds: custom calls without its
    compatibility guarantee (ValueError "Cannot serialize code with custom calls ...", e.g.
    MuJoCo Warp's) or host callbacks (NotImplementedError)."""
    return isinstance(error, NotImplementedError) or "custom call" in str(error)


def _per_leaf(shardings: Any, tree: Any) -> list:
    """`shardings`, a tree of shardings that is a prefix of `tree`, as one sharding per leaf of
    `tree` (flattened in its order)."""
    return jax.tree_util.tree_leaves(jax.tree_util.tree_map(
        lambda sharding, part: [sharding] * len(jax.tree_util.tree_leaves(part)), shardings,
        tree, is_leaf=lambda x: isinstance(x, jax.sharding.Sharding)))


class CachedLowered:
    """What `cached_lower` returns: `compile(compiler_options=None)` gives the `CachedProgram`
    (the persistent compilation cache supplies the executable if it has it)."""

    def __init__(self, lowered: jax.stages.Lowered, result_tree):
        self._lowered, self._result_tree = lowered, result_tree

    def compile(self, compiler_options: Optional[dict] = None) -> "CachedProgram":
        return CachedProgram(self._lowered.compile(compiler_options=compiler_options),
                             self._result_tree)


class CachedProgram:
    """What `CachedLowered.compile` returns: `program(*args)` calls the compiled program on the
    caller's pytrees; `memory_analysis()` is XLA's, as of `jax.stages.Compiled`."""

    def __init__(self, compiled: jax.stages.Compiled, result_tree):
        self._compiled, self._result_tree = compiled, result_tree

    def __call__(self, *args):
        return jax.tree_util.tree_unflatten(
            self._result_tree, self._compiled(*jax.tree_util.tree_leaves(list(args))))

    def memory_analysis(self):
        return self._compiled.memory_analysis()
