"""Measurements of `sac_jax.parallel` on 2 devices, for tests/test_parallel.py, which runs this
script in a subprocess with 2 forced CPU devices (XLA_FLAGS must be set before JAX is imported)
and asserts on the JSON object it prints, one entry per named check:

    XLA_FLAGS=--xla_force_host_platform_device_count=2 JAX_ENABLE_X64=1 \
        python -m tests.parallel_checks updates seeds one_device

The comparisons ("updates", "seeds", "one_device", "separate", "settings") compare two compiled programs
that round differently, over up to 768 updates, where training amplifies a rounding difference
by a factor of 1e4..1e5 (float32: 6e-8 became 1.5e-4..4e-3 relative at the first evaluation,
depending on the CPU's instruction set). They need JAX_ENABLE_X64=1 and run with the learner
state (parameters, targets, optimiser states, temperature) in float64 (`float64_train`), as the
x64 equivalence tests do: the same amplification then leaves about 1e-11, and a bound of 1e-9
holds on any CPU. Environments keep their float32 observations and rewards (their contract),
and the reported metrics stay float32 (`make_train` casts them). "learning" runs in float32.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import NamedSharding
from jax.sharding import PartitionSpec as P

import sac_jax
from sac_jax.train import make_train_parts
from sac_jax import parallel, selection
from sac_jax.compilation_cache import enable_compilation_cache
from sac_jax.program_cache import cached_lower
from tests.pendulum_shapes import cast_floats, pendulum_agent, pendulum_batch

# Pendulum-v1 shapes (O = 3, A = 1), global batch of 32. v2 with CleanRL's policy delay of 2:
# the compared update is the 4th, which runs the actor block (2 actor and temperature steps)
# inside its `lax.cond`; v1 runs its actor step directly.
UPDATE_CONFIGS = {
    "v2": sac_jax.SACConfig(env="Pendulum-v1", actor_hidden=(32, 32), critic_hidden=(32, 32),
                            batch_size=32, learning_starts=32, eval_every=32, total_steps=64,
                            policy_frequency=2),
}
UPDATE_CONFIGS["v1"] = UPDATE_CONFIGS["v2"].replace(
    variant="v1", learn_alpha=False, reward_scale=2.0, loss_coef=0.5, policy_frequency=1,
    update_order=("value", "actor", "critic"))
# The pendulum preset on 2 environments with 2 updates per iteration (its 1 update per
# environment step); on 2 devices, one environment and half of each batch per device.
TRAIN_CONFIG = sac_jax.PRESETS["pendulum"].replace(num_envs=2, updates_per_step=2)
# test_train's small configuration: 3 evaluations after 768 updates.
SMALL_CONFIG = sac_jax.PRESETS["pendulum"].replace(
    total_steps=1024, learning_starts=256, eval_every=256, batch_size=64, num_envs=2,
    updates_per_step=2, actor_hidden=(32, 32), critic_hidden=(32, 32), eval_episodes=2)


LEARNER_BOUND = 1e-9
"""Bound on the per-array relative difference (max|a - b| / max|b|) of two float64 learner
states after up to 768 updates: float64 rounding, 2^-52 = 2.2e-16, times the amplification of
the training loop over that horizon, which the same comparisons in float32 show to be at most
about 1e5 (float32's 2^-24 = 6e-8 became at most 4.2e-3 relative on AVX-512, AVX2 and SSE4.2
code): at most about 2e-11, so 1e-9 leaves a factor of 50. One float32 rounding error entering
the learner (what a float32 bug would bring) is amplified to about 1e-3."""
METRIC_ULPS = 512
"""Bound on a float32 metric's difference, in float32 ulps of its largest magnitude over the
run, between two runs whose float64 learners agree to 1e-9. A metric is the mean of a period's
n = 128 per-iteration float32 values, summed in float32 (an evaluation return: 200 float32
rewards summed): each of its 2n + 1 roundings may go the other way by one ulp of what it rounds,
up to k ulps of a term for the k-th partial sum, so after dividing by n at most n + 2 = 130 ulps
of the largest term; 512 allows the largest term to be about 4 times the largest period mean."""


def run_parallel_checks(*names, x64: bool = False) -> dict:
    """This script's checks NAMES in a subprocess with 2 forced CPU devices (added to the
    caller's XLA_FLAGS), with JAX_ENABLE_X64=1 if `x64`: the JSON object it prints."""
    from tests.subprocess_json import run_json

    env = {"XLA_FLAGS": "--xla_force_host_platform_device_count=2"}
    if x64:
        env["JAX_ENABLE_X64"] = "1"
    return run_json(["-m", "tests.parallel_checks", *names], **env)


def to_float64(tree):
    """`tree` with every floating leaf in float64 (needs JAX_ENABLE_X64=1)."""
    return cast_floats(tree, jnp.float64)


def float64_train(parts, metrics=lambda outputs: outputs):
    """`train(key, hyperparams=None) -> (runner, metrics)` that runs `parts` as `make_train`
    does (`init`, then `num_chunks` chunks in one scan) with the learner state, and the
    delivered actor kept from it, cast to float64 after `init`."""
    def train(key, hyperparams=None):
        runner = parts.init(key, hyperparams)
        sac = to_float64(runner.sac)
        runner = runner.replace(sac=sac, delivered=selection.init(sac.actor_params))
        runner = jax.lax.scan(lambda r, _: (parts.chunk(r), None), runner, None,
                              length=parts.num_chunks)[0]
        return runner, metrics(runner.outputs)
    return train


def float_dtypes(tree) -> list:
    """The dtypes of the floating leaves of `tree`, sorted."""
    return sorted({str(np.asarray(x).dtype) for x in jax.tree_util.tree_leaves(tree)
                   if np.issubdtype(np.asarray(x).dtype, np.floating)})


def learner_rel_diff(a, b) -> float:
    """Per array max|a - b| / max|b| over every floating array of two learner states
    (`SACState`: parameters, targets, optimiser moments, log alpha and alpha), max over arrays;
    0 where both are all zero."""
    worst = 0.0
    for x, y in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b), strict=True):
        x, y = np.asarray(x), np.asarray(y)
        assert x.shape == y.shape and x.dtype == y.dtype
        if not np.issubdtype(y.dtype, np.floating):
            continue
        scale = float(np.max(np.abs(y), initial=0.0))
        diff = float(np.max(np.abs(x.astype(np.float64) - y), initial=0.0))
        worst = max(worst, diff / scale if scale else diff)
    return worst


def metrics_ulps(a: dict, b: dict) -> float:
    """max over metrics of max_points |a - b| / ulp(max_points |b|): the difference in float32
    units in the last place of the metric's largest magnitude over the run; inf where `a` and
    `b` are not finite at the same entries. The metrics are float32 whatever the learner's
    dtype."""
    worst = 0.0
    for name in b:
        x, y = np.asarray(a[name], np.float64), np.asarray(b[name], np.float64)
        finite = np.isfinite(y)
        if not np.array_equal(finite, np.isfinite(x)) or not np.array_equal(x[~finite], y[~finite], equal_nan=True):
            return float("inf")
        if not finite.any():
            continue
        ulp = float(np.spacing(np.float32(np.max(np.abs(y[finite])))))
        worst = max(worst, float(np.max(np.abs(x - y)[finite])) / ulp)
    return worst


def max_abs(tree) -> float:
    return float(max(np.max(np.abs(np.asarray(x))) for x in jax.tree_util.tree_leaves(tree)))


def max_abs_diff(a, b) -> float:
    return max_abs(jax.tree_util.tree_map(lambda x, y: np.asarray(x) - np.asarray(y), a, b))


def relative_diff(a: dict, b: dict) -> float:
    """max over metrics and entries of |a - b| / max(|b|, 1e-6); NaN where `a` and `b` are not
    finite at the same entries."""
    worst = 0.0
    for name in b:
        x, y = np.asarray(a[name], np.float64), np.asarray(b[name], np.float64)
        finite = np.isfinite(y)
        if not np.array_equal(finite, np.isfinite(x)):
            return float("nan")
        worst = max(worst, float(np.max(np.abs(x - y)[finite] / np.maximum(
            np.abs(y[finite]), 1e-6), initial=0.0)))
    return worst


def relative_diff_per_point(a: dict, b: dict) -> list:
    """`relative_diff` of two runs' metrics at each evaluation point (last axis)."""
    points = np.shape(b["eval_return"])[-1]
    return [relative_diff({k: np.asarray(v)[..., p] for k, v in a.items()},
                          {k: np.asarray(v)[..., p] for k, v in b.items()})
            for p in range(points)]


def check_updates() -> dict:
    """One `sac_update` on a global batch of 32 with injected noise, float64: on one device, and
    data parallel over 2 devices as `parallel.make_data_parallel_parts` runs it (the update
    vmapped over 2 shares of 16 samples and the matching noise, axis "data", the shares split
    over the devices), each share's resulting state (parameters, targets, optimiser states,
    temperature) and metrics compared. The state first takes 3 single-device updates so Adam's
    moments are not at their first step. Control: the same without averaging over the axis."""
    mesh = parallel.make_mesh(parallel.DATA)
    split, whole = NamedSharding(mesh, P("data")), NamedSharding(mesh, P())
    batch_axis = {"critic": 0, "value": 0, "actor": 1, "temperature": 1}  # of each noise array

    def shares(x, axis):
        """x with its batch axis `axis` cut into 2 shares, on a new leading axis."""
        x = x.reshape(x.shape[:axis] + (2, x.shape[axis] // 2) + x.shape[axis + 1:])
        return jnp.moveaxis(x, axis, 0)
    update = jax.jit(sac_jax.sac_update)
    out = {}
    for name, config in UPDATE_CONFIGS.items():
        agent = pendulum_agent(config)
        state = to_float64(agent.init(jax.random.key(0)))
        for i in range(3):
            state = update(agent, state, pendulum_batch(jax.random.key(10 + i), 32),
                           jax.random.key(20 + i))[0]
        batch = pendulum_batch(jax.random.key(1), 32)
        noise = sac_jax.sample_noise(agent, jax.random.key(2), 32)
        single = jax.device_get(update(agent, state, batch, noise))

        def per_device(cfg):
            """Each share's (state, metrics) after the data-parallel update, stacked."""
            fn = jax.vmap(lambda s, b, n: sac_jax.sac_update(pendulum_agent(cfg), s, b, n),
                          in_axes=(None, 0, 0), out_axes=0, axis_name="data")
            return jax.device_get(jax.jit(fn, in_shardings=(whole, split, split))(
                state, jax.tree_util.tree_map(lambda x: shares(x, 0), batch),
                {name: shares(x, batch_axis[name]) for name, x in noise.items()}))

        averaged = per_device(config.replace(data_parallel_axis="data"))
        control = per_device(config)
        entry = {}
        for label, result in (("averaged", averaged), ("control", control)):
            devices = [jax.tree_util.tree_map(lambda x: x[d], result) for d in range(2)]
            entry[label] = {
                "state_diff": max(learner_rel_diff(d[0], single[0]) for d in devices),
                "between_devices": max_abs_diff(devices[0][0], devices[1][0]),
                "metrics_rel_diff": max(relative_diff(d[1], single[1]) for d in devices),
            }
        entry["learner_dtypes"] = float_dtypes(single[0])
        entry["metrics"] = sorted(single[1])
        out[name] = entry
    return out


def _seed_runs():
    """(keys, the float64 `make_train` loop of SMALL_CONFIG, its jitted vmap over the 2 seeds'
    keys and the result), shared by "seeds" and "separate"."""
    keys = jax.random.split(jax.random.key(3), 2)
    train = float64_train(make_train_parts(SMALL_CONFIG))
    return keys, train, jax.device_get(jax.jit(jax.vmap(train))(keys))


_SEED_RUNS = []


def seed_runs():
    if not _SEED_RUNS:
        _SEED_RUNS.append(_seed_runs())
    return _SEED_RUNS[0]


def check_seeds() -> dict:
    """Two seeds of the float64 `make_train` loop of SMALL_CONFIG sharded over the 2 devices
    (`over_seeds`) and vmapped on one device."""
    keys, train, plain = seed_runs()
    mesh = parallel.make_mesh(parallel.SEEDS)
    sharded = parallel.over_seeds(train, mesh)(keys)
    devices = sorted(d.id for d in sharded[1]["eval_return"].sharding.device_set)
    shard_rows = [s.data.shape[0] for s in sharded[1]["eval_return"].addressable_shards]
    sharded = jax.device_get(sharded)
    return {"devices": devices, "rows_per_device": shard_rows,
            "learner_dtypes": float_dtypes(plain[0].sac),
            "learner_rel_diff": learner_rel_diff(sharded[0].sac, plain[0].sac),
            "metrics_ulps": metrics_ulps(sharded[1], plain[1]),
            "metrics_rel_diff": relative_diff_per_point(sharded[1], plain[1]),
            "seeds_rel_diff": learner_rel_diff(
                jax.tree_util.tree_map(lambda x: x[0], plain[0].sac.actor_params),
                jax.tree_util.tree_map(lambda x: x[1], plain[0].sac.actor_params))}


def check_separate() -> dict:
    """The same two seeds run separately (`jax.jit(train)` on each key) against the vmap of
    "seeds"; test_train.py asserts on it."""
    keys, train, plain = seed_runs()
    runs = [jax.device_get(jax.jit(train)(key)) for key in keys]
    batched = [jax.tree_util.tree_map(lambda x: x[i], (plain[0].sac, plain[1]))
               for i in range(2)]
    return {"learner_dtypes": float_dtypes(runs[0][0].sac),
            "learner_rel_diff": [learner_rel_diff(b[0], r[0].sac)
                                 for b, r in zip(batched, runs)],
            "metrics_ulps": [metrics_ulps(b[1], r[1]) for b, r in zip(batched, runs)],
            "metrics_rel_diff": [relative_diff(b[1], r[1]) for b, r in zip(batched, runs)],
            "seeds_rel_diff": learner_rel_diff(runs[0][0].sac.actor_params,
                                               runs[1][0].sac.actor_params),
            "seeds_critic_loss_rel_diff": relative_diff(
                {"critic_loss": runs[0][1]["critic_loss"]},
                {"critic_loss": runs[1][1]["critic_loss"]})}


SETTINGS = (SMALL_CONFIG, SMALL_CONFIG.replace(actor_lr=1e-3, critic_lr=1e-3, gamma=0.95))
"""The swept settings of "settings": the first is SMALL_CONFIG itself."""


def check_settings() -> dict:
    """A sweep of SETTINGS x the 2 seeds of "seeds" in one vmapped float64 `make_train` loop
    (the settings traced, `sac_jax.hyperparams.stack`) against the four separate runs of each
    setting's own config on each key (`jax.jit(train)(key)`, its values constants)."""
    keys = jax.random.split(jax.random.key(3), 2)
    swept = sac_jax.hyperparams.stack([c for c in SETTINGS for _ in keys])
    train = float64_train(make_train_parts(SETTINGS[0]))
    sweep = jax.device_get(jax.jit(jax.vmap(train))(jnp.concatenate([keys, keys]), swept))
    learner, ulps = [], []
    for s, config in enumerate(SETTINGS):
        separate = jax.jit(float64_train(make_train_parts(config)))
        for k, key in enumerate(keys):
            run = jax.device_get(separate(key))
            swept_run = jax.tree_util.tree_map(lambda x: x[2 * s + k], (sweep[0].sac, sweep[1]))
            learner.append(learner_rel_diff(swept_run[0], run[0].sac))
            ulps.append(metrics_ulps(swept_run[1], run[1]))
    return {"swept": sorted(swept), "learner_dtypes": float_dtypes(sweep[0].sac),
            "learner_rel_diff": learner, "metrics_ulps": ulps,
            "settings_rel_diff": learner_rel_diff(
                jax.tree_util.tree_map(lambda x: x[0], sweep[0].sac.actor_params),
                jax.tree_util.tree_map(lambda x: x[2], sweep[0].sac.actor_params))}


def check_one_device() -> dict:
    """The float64 `make_data_parallel_parts` loop on a one-device mesh against the float64
    `make_train` loop, same key; the random-action prefill transitions of the buffer compared
    too."""
    key = jax.random.key(3)
    mesh = parallel.make_mesh(parallel.DATA, jax.devices()[:1])
    ours = jax.device_get(jax.jit(float64_train(
        parallel.make_data_parallel_parts(SMALL_CONFIG, mesh),
        parallel.data_parallel_metrics))(key))
    plain = jax.device_get(jax.jit(float64_train(make_train_parts(SMALL_CONFIG)))(key))
    prefill = SMALL_CONFIG.learning_starts
    return {"learner_dtypes": float_dtypes(plain[0].sac),
            "learner_rel_diff": learner_rel_diff(ours[0].sac, plain[0].sac),
            "metrics_ulps": metrics_ulps(ours[1], plain[1]),
            "metrics_rel_diff": relative_diff_per_point(ours[1], plain[1]),
            "prefill_diff": max_abs_diff(
                jax.tree_util.tree_map(lambda x: x[0, :prefill], ours[0].buffer.data),
                jax.tree_util.tree_map(lambda x: x[:prefill], plain[0].buffer.data))}


def check_shares() -> dict:
    """The initial state of a data-parallel run over the 2 devices: the environments (and
    keys) of device 0's share against a one-device run of that share from the same key, and
    against device 1's share (its own key, `fold_in(key, 1)`)."""
    key = jax.random.key(3)
    mesh = parallel.make_mesh(parallel.DATA)
    runner = jax.device_get(jax.jit(parallel.make_data_parallel_parts(SMALL_CONFIG, mesh).init)(
        key))
    alone = jax.device_get(jax.jit(make_train_parts(SMALL_CONFIG.replace(
        num_envs=SMALL_CONFIG.num_envs // 2)).init)(key))
    data = lambda x: np.asarray(jax.random.key_data(x) if jax.dtypes.issubdtype(
        x.dtype, jax.dtypes.prng_key) else x)
    shares = [[data(x)[d] for x in jax.tree_util.tree_leaves((runner.env, runner.key))]
              for d in range(2)]
    own = [data(x) for x in jax.tree_util.tree_leaves((alone.env, alone.key))]
    return {"share0_as_alone": all(np.array_equal(a, b) for a, b in zip(shares[0], own,
                                                                           strict=True)),
            "shares_differ": not np.array_equal(data(runner.env.env_state.obs)[0],
                                                data(runner.env.env_state.obs)[1])}


def check_learning() -> dict:
    """A data-parallel run of TRAIN_CONFIG over the 2 devices: its evaluation returns, and
    its delivered actor's mean return over 10 episodes of Gymnasium's Pendulum-v1 (the
    learner state, the delivered actor's included, is one for all devices: `DATA_AXES`)."""
    import gymnasium

    from sac_jax.saved_policy import SavedPolicy
    from sac_jax.train import agent_for
    from scripts.evaluate import gymnasium_returns

    mesh = parallel.make_mesh(parallel.DATA)
    runner, metrics = jax.device_get(
        jax.jit(parallel.make_data_parallel_train(TRAIN_CONFIG, mesh))(jax.random.key(0)))
    params = runner.sac.actor_params
    policy = SavedPolicy(TRAIN_CONFIG, {}, 0, agent_for(TRAIN_CONFIG)[0],
                         runner.delivered.actor_params)
    env = gymnasium.make("Pendulum-v1")
    try:
        gymnasium_return = float(np.mean(gymnasium_returns(policy, env, 10, seed=123)))
    finally:
        env.close()
    return {"eval_return": metrics["eval_return"].tolist(),
            "env_steps": metrics["env_steps"].tolist(),
            "buffer_size": np.asarray(runner.buffer.size).tolist(),
            "finite_params": bool(np.isfinite(max_abs(params))),
            "gymnasium_return": gymnasium_return}


def check_cached() -> dict:
    """A program of 4 seeds split over the 2 devices (`parallel.seed_mapping`) through
    `cached_lower`, twice into one directory (the second read back): how often it was traced,
    the files written, whether both give exactly what `seeds_program` gives, and how many
    devices hold the result's seed axis."""
    calls = []

    def step(state):
        calls.append(1)  # runs only while tracing
        return {"x": state["x"] * 2.0 + state["count"], "count": state["count"] + 1}

    axes = {"x": 0, "count": None}
    state = {"x": jnp.arange(12.0).reshape(4, 3), "count": jnp.float32(1.0)}
    expected = parallel.seeds_program(step, 4, (axes,), axes)(state)
    with tempfile.TemporaryDirectory() as directory:
        mapped, placement = parallel.seed_mapping(step, 4, (axes,), axes)
        traced = len(calls)
        outs = [cached_lower(mapped, "step", [state], state, directory, **placement).compile()(
            state) for _ in range(2)]
        files = sum(name.endswith(".jaxexport") for name in os.listdir(directory))
    return {"traces": len(calls) - traced, "files": files,
            "equal": [all(np.array_equal(a, b) for a, b in zip(
                jax.tree_util.tree_leaves(out), jax.tree_util.tree_leaves(expected)))
                for out in outs],
            "devices": [len(out["x"].sharding.device_set) for out in outs]}


def check_stored() -> dict:
    """Replay arrays of 4 seeds split over the 2 devices, cut to 6 of their 10 slots for a
    checkpoint (`run_checkpoint._host_replay`): whether they equal the whole array's first 6
    slots, and whether each is one new array of just those slots."""
    from sac_jax import run_checkpoint

    mesh = parallel.make_mesh(parallel.SEEDS)
    whole = jnp.arange(4 * 10 * 3, dtype=jnp.float32).reshape(4, 10, 3)
    split = jax.device_put(whole, NamedSharding(mesh, P(parallel.SEEDS)))
    stored = run_checkpoint._host_replay({"obs": split}, 6)["obs"]
    return {"shards": len(split.addressable_shards), "shape": list(stored.shape),
            "equal": bool(np.array_equal(stored, np.asarray(whole)[:, :6])),
            "new_array": stored.base is None}


CHECKS = {"updates": check_updates, "seeds": check_seeds, "separate": check_separate,
          "settings": check_settings, "one_device": check_one_device, "learning": check_learning,
          "cached": check_cached, "stored": check_stored, "shares": check_shares}
FLOAT64_CHECKS = ("updates", "seeds", "separate", "settings", "one_device")


def main(names):
    if jax.device_count() != 2:
        raise SystemExit(f"needs 2 devices, found {jax.devices()}; set XLA_FLAGS="
                         "--xla_force_host_platform_device_count=2")
    if jax.config.jax_enable_x64 != any(name in FLOAT64_CHECKS for name in names):
        raise SystemExit(f"checks {names}: set JAX_ENABLE_X64=1 for {FLOAT64_CHECKS} "
                         "(and only for them)")
    enable_compilation_cache()
    print(json.dumps({name: CHECKS[name]() for name in names}))


if __name__ == "__main__":
    main(sys.argv[1:] or sorted(CHECKS))
