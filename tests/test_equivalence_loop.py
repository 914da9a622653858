"""The whole training loop: sac_jax's `make_train` loop against seed 002's loop
(tests/reference/loop.py), from the same initial weights and environment state, both fed the
stream of random draws `sac_jax.record_draws` makes (prefill actions, policy noise, minibatch
slots, update noise), on Pendulum-v1 for 512 environment steps after learning starts (512
updates; the ring buffer of 384 wraps around; episodes are truncated at 200 steps and reset).
Machinery and configurations: tests/equivalence_loop.py; figures: docs/equivalence.md.

float64 (JAX x64 and torch double, in a subprocess): parameters (actor, critics, critic
targets) relative <= 1e-4 per tensor, alpha relative <= 1e-8, stored transitions <= 1e-4.
Not float64 rounding (1e-12 after 200 updates without the loop): the environment emits float32
observations and both buffers store float32, as Gymnasium and stable-baselines3 do. Once the
pendulum's instability has grown the two sides' float64 rounding differences far enough, one
float32 rounding of an observation or reward goes the other way (first at environment step
152, 24 steps into learning), and the training dynamics carry that 1e-7 from there. Measured
2.3e-6 and 1.5e-7 (parameters), 8e-11 and 4e-10 (alpha). A single stale observation planted in
the reference's buffer (`_StaleObsOnce`) moves the parameters by 0.28, 2800 times the bound.

float32: the same loop fans out (relative 0.24 after 512 updates, transitions 0.2 apart), as
200 updates on fixed batches do (test_equivalence_float32.py): parameters relative <= 1
guards against blow-ups only, alpha relative <= 1e-3 (measured 9e-6); the float64 test is the
exact check. Both precisions check the schedule exactly: the number of updates and of stored
transitions.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from tests.equivalence_loop import CONFIGS, measure

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _check_schedule(name, e):
    config = CONFIGS[name]
    assert e["env_steps"] - config.learning_starts >= 500, e
    updates = (config.total_steps - config.learning_starts) // config.num_envs * \
        config.updates_per_step
    assert e["updates"] == e["updates_reference"] == updates, e
    assert e["buffer_size"] == e["buffer_size_reference"] == config.buffer_size, e


@pytest.fixture(scope="module")
def float64_errors():
    env = dict(os.environ, JAX_ENABLE_X64="1")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [ROOT, env.get("PYTHONPATH")]))
    proc = subprocess.run([sys.executable, "-m", "tests.equivalence_loop"], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-4000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("name", list(CONFIGS))
def test_float64_loop_matches_the_reference(float64_errors, name):
    e = float64_errors[name]
    _check_schedule(name, e)
    assert e["params"] <= 1e-4, e
    assert e["alpha"] <= 1e-8 and e["log_alpha"] <= 1e-8, e
    assert e["buffer"] <= 1e-4, e


def test_float64_comparison_detects_a_planted_bug(float64_errors):
    e = float64_errors["seed"]
    assert e["stale_obs/params"] >= 100 * 1e-4, e


def test_float32_loop_stays_with_the_reference():
    e = measure("seed", "float32")
    _check_schedule("seed", e)
    assert e["params"] <= 1.0, e
    assert e["alpha"] <= 1e-3, e
