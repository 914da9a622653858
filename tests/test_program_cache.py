"""sac_jax.program_cache: a traced program is stored once and read back by later calls without
tracing, gives what `jax.jit` gives, donates when asked, and a damaged file is traced again; a
program split over devices is stored and read back too. An executable compiled in a process is
stored and loaded by later ones without lowering (in later processes too, found again after an
edit that leaves the computation as it was); one that JAX's persistent cache supplied is not
stored; a damaged one is compiled again and removed. A state's shapes are kept too, and read
back by a later process without tracing. Executables are compiled without source locations.
The XLA flag the scripts set before JAX starts changes the kernels' order, and only then."""

import json
import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sac_jax.program_cache import (cached_lower, cached_shapes, executable_file, program_file,
                                   without_locations)
from sac_jax.replay_buffer import Transition
from tests.parallel_checks import run_parallel_checks
from tests.subprocess_json import ROOT, run_json


def _step_counting_traces(calls, salt=None):
    """A step whose traces are counted in `calls`; `salt` (default: drawn afresh) makes it a
    computation that no earlier test run left in JAX's persistent compilation cache, which
    this test process keeps on disk (tests/conftest.py), so that this process compiles it."""
    salt = float(np.random.default_rng().uniform(1.0, 2.0)) if salt is None else salt

    def step(state, scale):
        calls.append(1)  # runs only while tracing
        key, sub = jax.random.split(state["key"])
        return {"key": key,
                "x": state["x"] * scale * salt + jax.random.normal(sub, state["x"].shape),
                "t": Transition(obs=state["t"].obs + 1, action=state["t"].action,
                                reward=state["t"].reward, next_obs=state["t"].next_obs,
                                terminated=state["t"].terminated)}
    return step


def _state():
    z = lambda: jnp.zeros(2)  # a buffer of its own each, so all can be donated
    return {"key": jax.random.key(0), "x": jnp.arange(3.0),
            "t": Transition(obs=z(), action=z(), reward=z(), next_obs=z(), terminated=z())}


def test_stored_once_then_read_without_tracing(tmp_path):
    calls = []
    step = _step_counting_traces(calls)
    state, scale = _state(), jnp.float32(2.0)
    first = cached_lower(step, "step", [state, scale], state, str(tmp_path)).compile()
    assert len(calls) == 1 and _files(tmp_path) == {".jaxexport": 1, ".xla": 1}
    again = cached_lower(step, "step", [state, scale], state, str(tmp_path)).compile()
    assert len(calls) == 1  # read back: not traced
    expected = jax.jit(step)(state, scale)
    for program in (first, again):
        out = program(state, scale)
        assert jax.tree_util.tree_structure(out) == jax.tree_util.tree_structure(expected)
        for a, b in zip(jax.tree_util.tree_leaves(out), jax.tree_util.tree_leaves(expected)):
            if jax.dtypes.issubdtype(a.dtype, jax.dtypes.prng_key):
                a, b = jax.random.key_data(a), jax.random.key_data(b)
            np.testing.assert_array_equal(a, b)


def _files(directory) -> dict:
    """How many files of each extension `directory` holds."""
    names = os.listdir(directory)
    return {ext: sum(n.endswith(ext) for n in names) for ext in (".jaxexport", ".xla")}


def _refuse_lowering(monkeypatch):
    """Makes lowering, or compiling anything lowered, fail the test."""
    def refused(*args, **kwargs):
        raise AssertionError("lowered or compiled")
    monkeypatch.setattr(jax.stages.Lowered, "compile", refused)
    monkeypatch.setattr(jax.stages.Traced, "lower", refused)


def test_a_stored_executable_is_loaded_without_lowering_and_donates(tmp_path, monkeypatch):
    state, scale = _state(), jnp.float32(2.0)
    step = _step_counting_traces([])
    expected = jax.jit(step)(state, scale)
    cached_lower(step, "step", [state, scale], state, str(tmp_path),
                 donate_first=True).compile()
    _refuse_lowering(monkeypatch)
    program = cached_lower(step, "step", [state, scale], state, str(tmp_path),
                           donate_first=True).compile()
    out = program(state, scale)
    np.testing.assert_array_equal(out["x"], expected["x"])
    np.testing.assert_array_equal(jax.random.key_data(out["key"]),
                                  jax.random.key_data(expected["key"]))
    assert state["x"].is_deleted() and not scale.is_deleted()
    assert program.memory_analysis().temp_size_in_bytes >= 0


def test_an_edit_that_leaves_the_computation_finds_its_executable(tmp_path, monkeypatch):
    """The same computation traced from other source lines under another name (as after an
    edit of sac_jax, whose source names the traced program's file): traced again, not
    compiled again."""
    salt = float(np.random.default_rng().uniform(1.0, 2.0))
    state, scale = _state(), jnp.float32(2.0)
    cached_lower(_step_counting_traces([], salt), "step", [state, scale], state,
                 str(tmp_path)).compile()
    calls = []

    def edited(state, scale):  # the same computation, written elsewhere
        return _step_counting_traces(calls, salt)(state, scale)

    monkeypatch.setattr(jax.stages.Lowered, "compile", lambda *a, **k: pytest.fail("compiled"))
    program = cached_lower(edited, "step, edited", [state, scale], state,
                           str(tmp_path)).compile()
    assert len(calls) == 1 and _files(tmp_path) == {".jaxexport": 2, ".xla": 1}
    np.testing.assert_array_equal(program(state, scale)["x"],
                                  jax.jit(edited)(state, scale)["x"])


def test_executables_across_processes_and_one_from_jaxs_cache_is_not_stored(tmp_path):
    """Process 1 compiles and stores the executable; process 2, with an empty program cache
    but JAX's cache from process 1, gets JAX's executable and stores none (on a CPU its copy
    would not run); process 3 loads process 1's without compiling (nor lowering, which on a
    CPU sets up the LAPACK kernels its Cholesky calls: loading does). All give the same."""
    cache, first, second = (str(tmp_path / name) for name in ("jax", "first", "second"))
    runs = [run_json(["-m", "tests.executable_cache_run", programs, cache])
            for programs in (first, second, first)]
    expected = (np.sin(np.arange(4.0, dtype=np.float32)) * 3.0 + np.arange(4.0)).tolist()
    for run in runs:
        np.testing.assert_allclose(run.pop("x"), expected, rtol=1e-6)
        np.testing.assert_allclose(run.pop("c"), np.sqrt(np.arange(4.0) + 1.0), rtol=1e-6)
        assert run.pop("n") == 1 and run.pop("donated")
    assert runs == [{"compiled": 1, "programs": 1, "executables": 1},
                    {"compiled": 1, "programs": 1, "executables": 0},
                    {"compiled": 0, "programs": 1, "executables": 1}]


def test_a_damaged_executable_is_compiled_again_with_one_warning(tmp_path):
    state, scale = _state(), jnp.float32(2.0)
    step = _step_counting_traces([])
    cached_lower(step, "step", [state, scale], state, str(tmp_path)).compile()
    (path,) = [tmp_path / name for name in os.listdir(tmp_path) if name.endswith(".xla")]
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))
    with pytest.warns(UserWarning, match="executable .* damaged .checksum mismatch.; compiling"):
        program = cached_lower(step, "step", [state, scale], state, str(tmp_path)).compile()
    # removed: this process's second compile came from JAX's cache, so none is stored again
    assert not path.exists()
    np.testing.assert_array_equal(program(state, scale)["x"], jax.jit(step)(state, scale)["x"])


def test_the_executable_file_name_depends_on_what_the_executable_does(monkeypatch):
    """The computation, the donated arguments, the compiler options and XLA's flags."""
    computation = b"\0" * 32
    name = executable_file(computation, (), None)
    names = {name, executable_file(b"\1" * 32, (), None), executable_file(computation, (0,), None),
             executable_file(computation, (), {"xla_backend_optimization_level": 1})}
    flags = os.environ.get("XLA_FLAGS", "")  # the suite's (conftest.py's, and the caller's)
    monkeypatch.setenv("XLA_FLAGS", f"{flags} --xla_cpu_max_isa=SSE4_2")
    names.add(executable_file(computation, (), None))
    assert len(names) == 5
    monkeypatch.setenv("XLA_FLAGS", flags)
    assert executable_file(computation, (), {}) == name


def test_the_file_name_depends_on_name_shapes_and_dtypes():
    state = _state()
    names = {program_file("step", [state]), program_file("other", [state]),
             program_file("step", [dict(state, x=jnp.arange(4.0))]),
             program_file("step", [dict(state, x=jnp.arange(3))])}
    assert len(names) == 4
    assert program_file("step", [state]) == program_file("step", [_state()])


def test_the_file_name_depends_on_jaxs_trace_settings():
    """A program traced under another matmul precision or PRNG setting is another program."""
    args = [jnp.zeros(3)]
    plain = program_file("p", args)
    with jax.default_matmul_precision("highest"):
        assert program_file("p", args) != plain
    with jax.threefry_partitionable(not jax.config.jax_threefry_partitionable):
        assert program_file("p", args) != plain
    assert program_file("p", args) == plain


def test_a_damaged_file_is_traced_again_and_replaced(tmp_path):
    calls = []
    step = _step_counting_traces(calls)
    state, scale = _state(), jnp.float32(2.0)
    cached_lower(step, "step", [state, scale], state, str(tmp_path)).compile()
    (path,) = [tmp_path / name for name in os.listdir(tmp_path) if name.endswith(".jaxexport")]
    path.write_bytes(b"not a program")
    program = cached_lower(step, "step", [state, scale], state, str(tmp_path)).compile()
    assert len(calls) == 2 and path.read_bytes() != b"not a program"
    np.testing.assert_array_equal(program(state, scale)["x"], jax.jit(step)(state, scale)["x"])


def test_the_first_argument_is_donated_when_asked(tmp_path):
    state, scale = _state(), jnp.float32(2.0)
    program = cached_lower(_step_counting_traces([]), "step", [state, scale], state,
                           str(tmp_path), donate_first=True).compile()
    program(state, scale)
    assert state["x"].is_deleted() and not scale.is_deleted()


def test_a_program_jax_export_cannot_keep_is_lowered_without_a_file(tmp_path):
    """A host callback (as MuJoCo Warp's custom calls) cannot be serialized: the program is
    lowered as `jax.jit` lowers it, computes the same, and leaves no file."""
    f = lambda x: jax.pure_callback(lambda a: np.asarray(a) * 2,
                                    jax.ShapeDtypeStruct((3,), jnp.float32), x) + 1
    x = jnp.arange(3.0)
    for _ in range(2):
        program = cached_lower(f, "callback", [x], x, str(tmp_path)).compile()
        np.testing.assert_array_equal(program(x), [1.0, 3.0, 5.0])
    assert os.listdir(tmp_path) == []


def test_a_result_of_another_structure_is_refused(tmp_path):
    state = _state()
    with pytest.raises(ValueError, match="returns"):
        cached_lower(lambda s: s["x"], "x", [state], state, str(tmp_path)).compile()


def test_a_file_with_flipped_bytes_is_traced_again_with_one_warning(tmp_path):
    """Bytes flipped in the middle of a stored program deserialized into a program that failed
    to compile ("SmallVector unable to grow"); its checksum now catches it first."""
    calls = []
    step = _step_counting_traces(calls)
    state, scale = _state(), jnp.float32(2.0)
    cached_lower(step, "step", [state, scale], state, str(tmp_path)).compile()
    (path,) = [tmp_path / name for name in os.listdir(tmp_path) if name.endswith(".jaxexport")]
    data = bytearray(path.read_bytes())
    middle = len(data) // 2
    data[middle:middle + 8] = bytes(b ^ 0xFF for b in data[middle:middle + 8])
    path.write_bytes(bytes(data))
    with pytest.warns(UserWarning, match="damaged .checksum mismatch.; tracing it again"):
        program = cached_lower(step, "step", [state, scale], state, str(tmp_path)).compile()
    assert len(calls) == 2 and path.read_bytes() != bytes(data)
    np.testing.assert_array_equal(program(state, scale)["x"], jax.jit(step)(state, scale)["x"])


def test_a_program_split_over_devices_is_stored_and_read_back():
    """On 2 forced CPU devices (tests/parallel_checks.py "cached"): traced once, one file, both
    calls give exactly what `seeds_program` gives, each result split over both devices."""
    check = run_parallel_checks("cached")["cached"]
    assert check == {"traces": 1, "files": 1, "equal": [True, True], "devices": [2, 2]}


@pytest.mark.parametrize("backend", ["cpu", "gpu"])
def test_compiler_options_per_backend_and_environment(monkeypatch, backend):
    """On a CPU, MuJoCo environments compile with MUJOCO_CPU_COMPILER_OPTIONS; elsewhere, and
    any other environment, with XLA's defaults."""
    from types import SimpleNamespace

    from sac_jax import compilation_cache as cc

    monkeypatch.setattr(jax, "default_backend", lambda: backend)
    mujoco, other = SimpleNamespace(simulates_mujoco=True), SimpleNamespace(simulates_mujoco=False)
    expected = cc.MUJOCO_CPU_COMPILER_OPTIONS if backend == "cpu" else {}
    assert cc.compiler_options(mujoco) == expected and cc.compiler_options(other) == {}


def test_every_compiler_option_is_one_this_xla_knows():
    """A compile accepts the options and refuses a name XLA does not know."""
    from sac_jax import compilation_cache as cc

    jax.jit(lambda x: x + 1).lower(1.0).compile(compiler_options=cc.MUJOCO_CPU_COMPILER_OPTIONS)
    with pytest.raises(Exception, match="xla_cpu_no_such_option"):
        jax.jit(lambda x: x + 2).lower(1.0).compile(compiler_options={"xla_cpu_no_such_option": 1})


SCHEDULE = """
import hashlib, json, os, sys
import jax, jax.numpy as jnp
from sac_jax.compilation_cache import sequential_cpu_scheduler
if sys.argv[1] == "late":
    jax.devices()
sequential_cpu_scheduler()
ws = [jnp.full((8, 8), i) for i in range(4)]  # four independent branches to order
text = jax.jit(lambda x: sum(jnp.tanh(x @ w) @ w for w in ws)).lower(ws[1]).compile().as_text()
print(json.dumps([os.environ["XLA_FLAGS"], hashlib.sha256(text.encode()).hexdigest()]))
"""


def test_the_sequential_cpu_scheduler_is_set_before_jax_starts_and_orders_kernels_anew():
    """Before JAX starts, the flag joins $XLA_FLAGS and XLA orders the kernels otherwise (the
    compiled program's schedule changes); after, or where the flag is set already, nothing
    changes."""
    from sac_jax.compilation_cache import SEQUENTIAL_CPU_SCHEDULER

    def run(when, flags):
        env = dict(os.environ, XLA_FLAGS=flags, JAX_PLATFORMS="cpu")
        proc = subprocess.run([sys.executable, "-c", SCHEDULE, when], env=env, text=True,
                              capture_output=True, cwd=ROOT)
        assert proc.returncode == 0, proc.stderr[-2000:]
        return json.loads(proc.stdout.splitlines()[-1])

    isa, concurrent = "--xla_cpu_max_isa=AVX2", SEQUENTIAL_CPU_SCHEDULER.replace("false", "true")
    early, late = run("early", isa), run("late", isa)
    kept = run("early", f"{isa} {concurrent}")
    assert early[0] == f"{isa} {SEQUENTIAL_CPU_SCHEDULER}"
    assert late[0] == isa and kept[0] == f"{isa} {concurrent}"
    assert early[1] != late[1] == kept[1]


def _shapes_of(tree):
    return [(x.shape, x.dtype, x.weak_type) for x in jax.tree_util.tree_leaves(tree)]


def test_shapes_are_stored_once_then_read_without_tracing(tmp_path):
    calls = []

    def trace():
        calls.append(1)
        return jax.eval_shape(lambda: {"key": jax.random.key(0), "x": jnp.zeros((3, 2)),
                                       "t": Transition(*[jnp.int32(0)] * 5), "w": 1.0})

    first = cached_shapes("state", trace, str(tmp_path))
    again = cached_shapes("state", trace, str(tmp_path))
    assert len(calls) == 1 and [p.suffix for p in tmp_path.iterdir()] == [".shapes"]
    assert jax.tree_util.tree_structure(again) == jax.tree_util.tree_structure(first)
    assert _shapes_of(again) == _shapes_of(first) == _shapes_of(trace())
    assert all(x.sharding is None for x in jax.tree_util.tree_leaves(again))
    cached_shapes("other state", trace, str(tmp_path))  # another name: traced, a file of its own
    assert len(calls) == 3 and len(os.listdir(tmp_path)) == 2
    assert _shapes_of(cached_shapes("state", trace, None)) == _shapes_of(first)
    assert len(calls) == 4 and len(os.listdir(tmp_path)) == 2  # no directory: always traced


def test_damaged_shapes_are_traced_again_with_one_warning_and_replaced(tmp_path):
    calls = []
    trace = lambda: calls.append(1) or jax.eval_shape(lambda: jnp.zeros(3))
    cached_shapes("state", trace, str(tmp_path))
    (path,) = tmp_path.iterdir()
    data = bytearray(path.read_bytes())
    data[-1] ^= 0xFF
    path.write_bytes(bytes(data))
    with pytest.warns(UserWarning, match="shapes .* damaged .checksum mismatch.; tracing"):
        assert cached_shapes("state", trace, str(tmp_path)).shape == (3,)
    assert len(calls) == 2
    assert cached_shapes("state", trace, str(tmp_path)).shape == (3,) and len(calls) == 2


def test_the_state_template_is_read_back_in_a_later_process(tmp_path):
    """A warm process takes the state's shapes from the cache (its memory check traces
    nothing), the same as the trace gives, importing MJX's classes as the environments do:
    without Warp (1.3 s of imports where warp-lang is installed, as the test extra has it)."""
    runs = [run_json(["-m", "tests.state_shapes_run", str(tmp_path)]) for _ in range(2)]
    assert [run["traced"] for run in runs] == [True, False]
    assert runs[0]["shapes"] == runs[1]["shapes"] and runs[1]["files"] == 1
    assert not runs[1]["warp"]


def test_an_executable_is_compiled_without_source_locations():
    state = {"key": jax.random.key(0), "x": jnp.arange(4.0),
             "t": Transition(*(jnp.zeros(2),) * 4, terminated=jnp.zeros(2, bool))}
    # a computation that JAX's persistent cache (whose keys leave locations out) cannot hold
    lowered = jax.jit(_step_counting_traces([])).lower(state, 2.0)
    assert 'loc("jit(step)/' in lowered.as_text(debug_info=True)  # XLA's op_name metadata
    compiled = without_locations(lowered).compile()
    assert 'loc("' not in lowered.as_text(debug_info=True)
    assert 'op_name="jit(step)' not in compiled.as_text()
