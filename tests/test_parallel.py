"""sac_jax.parallel. Device checks run in a subprocess with 2 forced CPU devices (XLA_FLAGS must
be set before JAX is imported; tests/parallel_checks.py measures, the tests here judge), the
comparisons of two programs with the learner state in float64 (JAX_ENABLE_X64=1 there; the
session fixture `float64_checks` of conftest.py, shared with test_train.py): a data-parallel update equals the single-device update on the same global batch and noise, and
fails to without the averaging; seeds sharded over devices equal the unsharded vmap; a
one-device mesh reproduces `make_train`; a data-parallel run learns Pendulum-v1. Without
devices: the one-seed program gives what the vmap gives; configs and meshes are checked; seeds
split into equal groups; scripts' one CPU device per core (in subprocesses)."""

import json
import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sac_jax import PRESETS, parallel
from tests.parallel_checks import LEARNER_BOUND, METRIC_ULPS, run_parallel_checks
from tests.subprocess_json import run_json


@pytest.fixture(scope="module")
def checks(float64_checks):
    """parallel_checks.py's "updates", "seeds" and "one_device" (float64)."""
    return float64_checks


@pytest.mark.parametrize("variant", ["v2", "v1"])
def test_data_parallel_update_equals_the_single_device_update(checks, variant):
    """float64: the devices' half-batch means, averaged, round differently from the whole-batch
    mean, by about 16 ulps (2^-52 each) of the 16 summed terms, which cancellation in the
    gradients and Adam's normalisation (g / sqrt(v)) amplify by at most 1e4: bound 1e-10 per
    array relative on the state and relative on the metrics (float32 showed 6e-8 and 1.7e-7
    for the 2^-24 of its rounding; the control below differs by 0.07 and 29%). Both devices hold
    bit-identical states (bit-exact: the averaged update is one computation)."""
    check = checks["updates"][variant]
    assert check["learner_dtypes"] == ["float64"], check
    assert {"critic_loss", "actor_loss", "entropy", "q", "alpha"} <= set(check["metrics"])
    assert ("alpha_loss" if variant == "v2" else "value_loss") in check["metrics"]
    averaged = check["averaged"]
    assert averaged["state_diff"] <= 1e-10, averaged
    assert averaged["metrics_rel_diff"] <= 1e-10, averaged
    assert averaged["between_devices"] == 0.0, averaged


@pytest.mark.parametrize("variant", ["v2", "v1"])
def test_without_averaging_the_update_differs(checks, variant):
    """The same vmapped, sharded update with `data_parallel_axis=None`: each device steps on its
    own half-batch, so the check above would fail (measured 0.07 on the state between devices,
    29% on metrics; asserted 1e-3 and 1e-2, orders of magnitude above the bound above)."""
    control = checks["updates"][variant]["control"]
    assert control["state_diff"] > 1e-3 and control["between_devices"] > 1e-3, control
    assert control["metrics_rel_diff"] > 1e-2, control


def test_seeds_sharded_over_devices_equal_the_unsharded_vmap(checks):
    """Each device runs one of the two seeds, 768 updates with the learner in float64: a vmap
    over 1 seed rounds differently from a vmap over 2, by float64 rounding amplified by the run
    (`LEARNER_BOUND`); the float32 metrics then agree to `METRIC_ULPS` (measured: 1.9e-12 and
    bit-identical). The two seeds' actor parameters differ by more than 30% of their scale."""
    check = checks["seeds"]
    assert check["devices"] == [0, 1] and check["rows_per_device"] == [1, 1]
    assert check["learner_dtypes"] == ["float64"], check
    assert check["learner_rel_diff"] <= LEARNER_BOUND, check
    assert check["metrics_ulps"] <= METRIC_ULPS, check
    assert check["seeds_rel_diff"] > 0.3, check


def test_one_device_mesh_reproduces_make_train(checks):
    """The random-action prefill transitions agree to one float32 rounding of the observations
    (device 0 keeps the run's key; the physics is float64 here, so at most one observation
    rounding may go the other way: one ulp of |obs| <= 8, spacing(8) = 9.5e-7; measured
    bit-identical); then the same run, learner in float64: `LEARNER_BOUND` and `METRIC_ULPS`
    (measured 5e-15 and bit-identical)."""
    check = checks["one_device"]
    assert check["learner_dtypes"] == ["float64"], check
    assert check["prefill_diff"] <= np.spacing(np.float32(8.0)), check
    assert check["learner_rel_diff"] <= LEARNER_BOUND, check
    assert check["metrics_ulps"] <= METRIC_ULPS, check


@pytest.mark.slow
def test_data_parallel_training_learns_pendulum():
    """The pendulum preset (2 environments, 2 updates per iteration) spread over 2 devices
    delivers a policy that reaches the task's threshold of -250 in Gymnasium's Pendulum-v1
    (a random policy scores about -1200)."""
    check = run_parallel_checks("learning")["learning"]
    assert check["env_steps"][-1] == 11_000 and check["buffer_size"] == 5_500, check
    assert check["gymnasium_return"] >= -250.0, check
    assert check["finite_params"]


@pytest.fixture(scope="module")
def device_checks():
    """parallel_checks.py's "stored" and "shares" (float32), in one subprocess."""
    return run_parallel_checks("stored", "shares")


def test_a_checkpoint_cuts_each_devices_replay_shard_without_assembling_the_buffer(
        device_checks):
    """Seeds split over 2 devices: the stored replay arrays are the filled slots of each
    device's shard, joined in seed order into one new array (`jax.device_get` had assembled
    all slots first: a whole replay buffer more at every checkpoint)."""
    check = device_checks["stored"]
    assert check == {"shards": 2, "shape": [4, 6, 3], "equal": True, "new_array": True}, check


def test_each_device_of_a_data_parallel_run_steps_its_own_environments(device_checks):
    """Device 0's share starts as a one-device run of it from the run's key, device 1's from
    its own key: with one key for both, the devices would collect the same transitions."""
    assert device_checks["shares"] == {"share0_as_alone": True, "shares_differ": True}


def test_one_seed_program_is_the_function_between_taking_and_restoring_the_seed_axis():
    """`over_seed_axis` for one seed gives what `jax.vmap` gives (integer arithmetic, so no
    rounding can differ): mapped parts keep their leading axis of 1, unmapped (None) parts stay
    as they are; in_axes as one int or per argument."""
    axes = {"x": 0, "count": None}
    step = lambda state, k: ({"x": state["x"] * 2 + state["count"] + k,
                              "count": state["count"] + 1}, k.sum())
    state = {"x": jnp.arange(6).reshape(1, 2, 3), "count": jnp.int32(5)}
    k = jnp.asarray([[1, 2, 3]])
    for fn, in_axes, out_axes, args in [
            (step, (axes, 0), (axes, 0), (state, k)),
            (lambda k: {"x": k * 3, "count": jnp.int32(0)}, 0, axes, (k,))]:
        one = jax.jit(parallel.over_seed_axis(fn, 1, in_axes, out_axes))(*args)
        vmapped = jax.jit(jax.vmap(fn, in_axes, out_axes))(*args)
        assert jax.tree_util.tree_structure(one) == jax.tree_util.tree_structure(vmapped)
        for a, b in zip(jax.tree_util.tree_leaves(one), jax.tree_util.tree_leaves(vmapped)):
            assert a.shape == b.shape and a.dtype == b.dtype
            np.testing.assert_array_equal(a, b)


def test_local_config_divides_the_sizes_and_keeps_the_schedule():
    config = PRESETS["fast"]
    local = parallel.local_config(config, 4)
    assert (local.num_envs, local.batch_size, local.buffer_size) == (2, 64, 5_120)
    assert (local.learning_starts, local.eval_every, local.total_steps) == (256, 256, 5_120)
    assert local.num_evals == config.num_evals
    assert local.prefill_iterations == config.prefill_iterations
    assert local.iterations_per_eval == config.iterations_per_eval
    assert local.data_parallel_axis == parallel.DATA
    assert parallel.local_config(config, 1).replace(data_parallel_axis=None) == config


def test_local_config_rejects_sizes_the_devices_do_not_divide():
    with pytest.raises(ValueError, match=r"SACConfig\.num_envs=8: must be a multiple of the 3"):
        parallel.local_config(PRESETS["fast"], 3)
    with pytest.raises(ValueError, match=r"SACConfig\.batch_size=100: .* 8 devices"):
        parallel.local_config(PRESETS["fast"].replace(batch_size=100), 8)
    with pytest.raises(ValueError, match="num_devices=0"):
        parallel.local_config(PRESETS["fast"], 0)


def test_a_mesh_of_several_axes_is_rejected():
    mesh = jax.sharding.Mesh(np.array(jax.devices()[:1]).reshape(1, 1), ("seeds", "data"))
    with pytest.raises(ValueError, match=r"mesh axes \('seeds', 'data'\): .*exactly one axis"):
        parallel.make_data_parallel_parts(PRESETS["fast"], mesh)
    with pytest.raises(ValueError, match="exactly one axis"):
        parallel.over_seeds(lambda key: key, mesh)


def test_seeds_split_into_the_most_equal_groups_the_devices_allow():
    devices = ["d0", "d1", "d2", "d3"]
    assert parallel.seed_devices(16, devices) == devices
    assert parallel.seed_devices(6, devices) == ["d0", "d1", "d2"]
    assert parallel.seed_devices(2, devices) == ["d0", "d1"]
    assert parallel.seed_devices(7, devices) == ["d0"]
    assert parallel.seed_devices(1, devices) == ["d0"]


CPU_DEVICES = ("import json, os, sys, jax; from sac_jax import parallel; "
               "sys.argv[1] == 'late' and jax.devices(); "
               "parallel.cpu_device_per_core(json.loads(sys.argv[2])); "
               "print(json.dumps([len(jax.devices()), os.environ.get('PJRT_NPROC')]))")
CORES = len(os.sched_getaffinity(0))
USED = {seeds: len(parallel.seed_devices(seeds, range(CORES))) for seeds in (3, 64)}


@pytest.mark.parametrize("when, seeds, env, expected", [
    ("early", None, {}, [CORES, None]),
    ("early", 64, {}, [USED[64], "1" if USED[64] == 1 else None]),  # as many as seed_devices
    ("early", 3, {}, [USED[3], "1" if USED[3] == 1 else None]),  # uses (on 2 cores: 1 for 3)
    ("early", 1, {}, [1, "1"]),  # one device, and a runtime of one thread
    ("early", 1, {"PJRT_NPROC": "2"}, [1, "2"]),  # a thread count set already stays
    ("late", 16, {}, [1, None]),  # the backends had started: their devices stay
    ("early", 16, {"XLA_FLAGS": "--xla_force_host_platform_device_count=3"}, [3, None]),
    ("early", 16, {"JAX_NUM_CPU_DEVICES": "1"}, [1, None])])
def test_scripts_make_one_cpu_device_per_core_and_seed_unless_a_count_is_set(
        when, seeds, env, expected):
    env = {"JAX_NUM_CPU_DEVICES": "-1", "JAX_PLATFORMS": "cpu", "PJRT_NPROC": None, **env}
    assert run_json(["-c", CPU_DEVICES, when, json.dumps(seeds)], **env) == expected


@pytest.mark.parametrize("platforms, only_cpu", [("cpu", True), ("cuda,cpu", False),
                                                 ("tpu", False)])
def test_one_runtime_thread_only_where_jax_starts_its_cpu_backend_alone(
        monkeypatch, platforms, only_cpu):
    """$PJRT_NPROC also sizes a GPU client's host thread pool: it is left alone there."""
    monkeypatch.delenv("PJRT_NPROC", raising=False)
    saved = jax.config.jax_platforms
    try:
        jax.config.update("jax_platforms", platforms)
        parallel.single_thread_cpu_runtime()
    finally:
        jax.config.update("jax_platforms", saved)
    assert os.environ.get("PJRT_NPROC") == ("1" if only_cpu else None)
