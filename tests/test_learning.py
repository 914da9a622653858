"""Learning tests: each preset trains with the settings a user gets, and must reach the task's
threshold (deterministic evaluation return, mean over `eval_episodes` episodes)."""

import numpy as np
import pytest

from sac_jax import PRESETS
from sac_jax.run import run_training

pytestmark = pytest.mark.slow


def final_returns(config, seeds):
    return run_training(config, seeds=seeds).metrics["eval_return"][:, -1]


@pytest.mark.parametrize("hidden_dtype", ["float32", "bfloat16"])
def test_fast_preset_solves_inverted_pendulum_v5_for_two_of_two_seeds(hidden_dtype):
    """Each seed solves (`summary.json`'s `solved_at_step`: some evaluation reaches 950) and
    stays solved: the median of its evaluations from that one on is >= 950. A single late dip
    passes; a policy that loses the task does not. (H100, 256 seeds, 2026-11-23, BENCHMARKS.md:
    all solved, the median seed at 7,168 steps; 254 stayed solved by this measure, 251 also
    ended at >= 950. Here seed 1 ends at 1000; seed 0 solves at 8,192 steps, holds 1000 and
    dips to 192 at the last evaluation.) With bfloat16 hidden layers (H100, 256 seeds, three
    runs of 2026-11-23: all solved in each, 245-249 ended at >= 950 against 247-248 in float32
    in the same calls; here the seeds solve at 9,216 and 7,168 steps and end at 1000)."""
    config = PRESETS["fast"].replace(hidden_dtype=hidden_dtype)
    returns = run_training(config, seeds=2).metrics["eval_return"]
    assert np.all(np.max(returns, axis=1) >= 950.0), returns
    for seed_returns in returns:
        since_solved = seed_returns[np.argmax(seed_returns >= 950.0):]
        assert np.median(since_solved) >= 950.0, returns


def test_pendulum_preset_reaches_minus_250_on_pendulum_v1():
    returns = final_returns(PRESETS["pendulum"], seeds=1)
    assert np.all(returns >= -250.0), returns


def test_v1_preset_learns_inverted_pendulum():
    returns = final_returns(PRESETS["v1"], seeds=1)
    assert np.all(returns >= 950.0), returns
