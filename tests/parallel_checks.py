"""Measurements of `sac_jax.parallel` on 2 devices, for tests/test_parallel.py, which runs this
script in a subprocess with 2 forced CPU devices (XLA_FLAGS must be set before JAX is imported)
and asserts on the JSON object it prints, one entry per named check:

    XLA_FLAGS=--xla_force_host_platform_device_count=2 python tests/parallel_checks.py updates seeds
"""

from __future__ import annotations

import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from jax.sharding import NamedSharding  # noqa: E402
from jax.sharding import PartitionSpec as P  # noqa: E402

import sac_jax  # noqa: E402
from sac_jax import parallel  # noqa: E402
from sac_jax.compilation_cache import enable_compilation_cache  # noqa: E402

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


def _pendulum_agent(config):
    return sac_jax.make_agent(config, 3, 1, -2.0, 2.0)


def _global_batch(key, batch_size):
    k = jax.random.split(key, 4)
    return sac_jax.Transition(
        obs=jax.random.normal(k[0], (batch_size, 3)),
        action=jax.random.uniform(k[1], (batch_size, 1), minval=-2, maxval=2),
        reward=jax.random.normal(k[2], (batch_size,)),
        next_obs=jax.random.normal(k[3], (batch_size, 3)),
        terminated=(jnp.arange(batch_size) % 5 == 0).astype(jnp.float32))


def check_updates() -> dict:
    """One `sac_update` on a global batch of 32 with injected noise: on one device, and data
    parallel over 2 devices as `parallel.make_data_parallel_parts` runs it (the update vmapped
    over 2 shares of 16 samples and the matching noise, axis "data", the shares split over the
    devices), each share's resulting state (parameters, targets, optimiser states, temperature)
    and metrics compared. The state first takes 3 single-device updates so Adam's moments are
    not at their first step. Control: the same without averaging over the axis."""
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
        agent = _pendulum_agent(config)
        state = agent.init(jax.random.key(0))
        for i in range(3):
            state = update(agent, state, _global_batch(jax.random.key(10 + i), 32),
                           jax.random.key(20 + i))[0]
        batch = _global_batch(jax.random.key(1), 32)
        noise = sac_jax.sample_noise(agent, jax.random.key(2), 32)
        single = jax.device_get(update(agent, state, batch, noise))

        def per_device(cfg):
            """Each share's (state, metrics) after the data-parallel update, stacked."""
            fn = jax.vmap(lambda s, b, n: sac_jax.sac_update(_pendulum_agent(cfg), s, b, n),
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
                "state_diff": max(max_abs_diff(d[0], single[0]) for d in devices),
                "between_devices": max_abs_diff(devices[0][0], devices[1][0]),
                "metrics_rel_diff": max(relative_diff(d[1], single[1]) for d in devices),
            }
        entry["params_scale"] = max_abs((single[0].actor_params, single[0].critic_params))
        entry["metrics"] = sorted(single[1])
        out[name] = entry
    return out


def check_seeds() -> dict:
    """Two seeds of `make_train(SMALL_CONFIG)` sharded over the 2 devices (`over_seeds`) and
    vmapped on one device."""
    keys = jax.random.split(jax.random.key(3), 2)
    train = sac_jax.make_train(SMALL_CONFIG)
    mesh = parallel.make_mesh(parallel.SEEDS)
    sharded = parallel.over_seeds(train, mesh)(keys)
    devices = sorted(d.id for d in sharded[1]["eval_return"].sharding.device_set)
    shard_rows = [s.data.shape[0] for s in sharded[1]["eval_return"].addressable_shards]
    sharded = jax.device_get(sharded)
    plain = jax.device_get(jax.jit(jax.vmap(train))(keys))
    return {"devices": devices, "rows_per_device": shard_rows,
            "metrics_rel_diff": relative_diff_per_point(sharded[1], plain[1]),
            "params_diff": max_abs_diff(sharded[0].sac.actor_params, plain[0].sac.actor_params),
            "params_scale": max_abs(plain[0].sac.actor_params),
            "seeds_params_diff": max_abs_diff(
                jax.tree_util.tree_map(lambda x: x[0], plain[0].sac.actor_params),
                jax.tree_util.tree_map(lambda x: x[1], plain[0].sac.actor_params))}


def check_one_device() -> dict:
    """`make_data_parallel_train` on a one-device mesh against `make_train`, same key; the
    random-action prefill transitions of the buffer compared too."""
    key = jax.random.key(3)
    mesh = parallel.make_mesh(parallel.DATA, jax.devices()[:1])
    ours = jax.device_get(jax.jit(parallel.make_data_parallel_train(SMALL_CONFIG, mesh))(key))
    plain = jax.device_get(jax.jit(sac_jax.make_train(SMALL_CONFIG))(key))
    prefill = SMALL_CONFIG.learning_starts
    return {"metrics_rel_diff": relative_diff_per_point(ours[1], plain[1]),
            "params_diff": max_abs_diff(ours[0].sac.actor_params, plain[0].sac.actor_params),
            "params_scale": max_abs(plain[0].sac.actor_params),
            "prefill_diff": max_abs_diff(
                jax.tree_util.tree_map(lambda x: x[0, :prefill], ours[0].buffer.data),
                jax.tree_util.tree_map(lambda x: x[:prefill], plain[0].buffer.data))}


def check_learning() -> dict:
    """A data-parallel run of TRAIN_CONFIG over the 2 devices: its evaluation returns."""
    mesh = parallel.make_mesh(parallel.DATA)
    runner, metrics = jax.device_get(
        jax.jit(parallel.make_data_parallel_train(TRAIN_CONFIG, mesh))(jax.random.key(0)))
    params = runner.sac.actor_params
    return {"eval_return": metrics["eval_return"].tolist(),
            "env_steps": metrics["env_steps"].tolist(),
            "buffer_size": np.asarray(runner.buffer.size).tolist(),
            "finite_params": bool(np.isfinite(max_abs(params)))}


CHECKS = {"updates": check_updates, "seeds": check_seeds, "one_device": check_one_device,
          "learning": check_learning}


def main(names):
    if jax.device_count() != 2:
        raise SystemExit(f"needs 2 devices, found {jax.devices()}; set XLA_FLAGS="
                         "--xla_force_host_platform_device_count=2")
    enable_compilation_cache()
    print(json.dumps({name: CHECKS[name]() for name in names}))


if __name__ == "__main__":
    main(sys.argv[1:] or sorted(CHECKS))
