"""The pieces of benchmarks/brax_peer.py that its figures rest on: the compile clock's union of
event spans, the stand-in for `jax.device_put_replicated`, and the mapping onto Brax's
`sac.train` arguments (whose evaluation points must fall where ours do), and the rate both
are measured at."""

from __future__ import annotations

import importlib.util
import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sac_jax.presets import PRESETS

PATH = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                    "benchmarks", "brax_peer.py")


@pytest.fixture(scope="module")
def peer():
    spec = importlib.util.spec_from_file_location("brax_peer", PATH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_compile_clock_counts_nested_and_overlapping_spans_once(peer):
    clock = peer.CompileClock()
    event = peer.COMPILE_EVENTS[0]
    for start, end in [(10, 20), (12, 15), (18, 25), (30, 31), (40, 50)]:  # (12, 15) nested
        clock._on_span(event, start, end, fun_name="f")
    clock._on_span("/jax/some/other_event", 0, 100)
    assert clock.seconds(0, 100) == pytest.approx(15 + 1 + 10)
    assert clock.seconds(14, 45) == pytest.approx(11 + 1 + 5)  # clipped at both ends
    assert clock.seconds(26, 29) == 0


def test_device_put_replicated_stacks_on_every_device(peer):
    devices = jax.local_devices()
    tree = {"w": jnp.arange(6.0).reshape(2, 3), "n": jnp.uint32(7)}
    out = peer.device_put_replicated(tree, devices)
    for key, leaf in tree.items():
        assert out[key].shape == (len(devices),) + leaf.shape
        for shard in out[key].addressable_shards:
            np.testing.assert_array_equal(np.asarray(shard.data)[0], np.asarray(leaf))


@pytest.mark.parametrize("changes", [{}, dict(total_steps=21_000, buffer_size=21_000),
                                     dict(total_steps=768, learning_starts=256,
                                          buffer_size=768, eval_every=256)])
def test_brax_arguments_evaluate_where_we_do(peer, changes):
    config = PRESETS["fast"].replace(**changes)
    kw = peer.brax_arguments(config)
    # sac.train: prefill ceil(min_replay / num_envs) actor steps, then num_evals - 1 epochs of
    # ceil((num_timesteps - prefill env steps) / ((num_evals - 1) num_envs)) actor steps each
    prefill = -(-kw["min_replay_size"] // kw["num_envs"]) * kw["num_envs"]
    epoch = -(-(kw["num_timesteps"] - prefill) // ((kw["num_evals"] - 1) * kw["num_envs"]))
    brax_points = [prefill + (i + 1) * epoch * kw["num_envs"] for i in range(kw["num_evals"] - 1)]
    ours = [config.learning_starts + (i + 1) * config.eval_every for i in range(config.num_evals)]
    assert brax_points == ours
    assert (kw["batch_size"], kw["grad_updates_per_step"], kw["learning_rate"]) == (
        config.batch_size, config.updates_per_step, config.actor_lr)


def test_brax_arguments_refuse_what_brax_cannot_express(peer):
    with pytest.raises(ValueError, match="critic_lr=0.0003"):
        peer.brax_arguments(PRESETS["fast"].replace(critic_lr=3e-4))


def test_env_steps_per_second_run_to_the_first_solved_point(peer):
    """Both trainers' rates cover the same steps: from the call to the first solved point,
    compile time out, not Brax's later full-length evaluations (ours stops there)."""
    class Clock:  # 10 s of compiling, all before the first point
        def seconds(self, t0, t1):
            return min(t1 - t0, 10.0)

    points = [(1024, 100.0, 112.0), (2048, 960.0, 114.0), (3072, 1000.0, 130.0)]
    out = peer.figures(Clock(), 100.0, 131.0, points, threshold=950.0)
    assert out["solved_at_step"] == 2048 and out["solve_train_s"] == 4.0
    assert out["env_steps_per_s"] == 512.0  # 2048 steps in 4 s, not 3072 in 21 s
    unsolved = peer.figures(Clock(), 100.0, 131.0, points[:1], threshold=950.0)
    assert unsolved["env_steps_per_s"] == round(1024 / 21.0, 1)
