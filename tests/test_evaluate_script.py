"""scripts/evaluate.py on a small Pendulum-v1 run: ours is `sac_jax.evaluate` on the stored
parameters; Gymnasium's Pendulum-v1 started from ours' initial states gives the same returns
episode by episode; bad input ends with one line and a non-zero exit code."""

import json
import shutil
import sys

import gymnasium
import jax
import numpy as np
import pytest

import envs
import sac_jax
from sac_jax import run_checkpoint, run_dir
from sac_jax.train import agent_for
from scripts import evaluate as evaluate_script
from tests.saved_runs import (damage_checkpoint, fails_in_one_line, trained_pendulum, untrained,
                              with_planted_delivered_actor)

PAIRED_TOLERANCE = 0.1
"""|ours - Gymnasium| per Pendulum-v1 episode from the same initial state (returns ~ -1e3):
float32 JAX against float64 NumPy over 200 steps of the same deterministic policy, i.e. float32
rounding (2^-24 relative a step) amplified by 200 closed-loop steps. The amplification is
measured, not derived (a Lipschitz bound over 200 steps is vacuous); tests/test_envs_x64.py
checks the same dynamics to float64 rounding."""


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A trained run whose delivered and last actors differ."""
    return with_planted_delivered_actor(
        trained_pendulum(str(tmp_path_factory.mktemp("runs") / "pendulum")))


def _json(capsys, argv):
    assert evaluate_script.main(argv + ["--json"]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("policy", ["best", "last"])
def test_ours_is_sac_evaluate_on_the_stored_parameters(run, capsys, policy):
    """The script's returns are those of the jitted `sac_jax.evaluate` on the delivered actor
    (on the last with `--policy last`), bit for bit (the same program on the same inputs);
    the mean is theirs to float64 rounding of a sum of 6 terms."""
    result = _json(capsys, [run, "--which", "ours", "--episodes", "6", "--episode-seed", "3",
                            "--policy", policy])
    config, _, runner, _ = run_checkpoint.load_checkpoint(run)
    agent, env = agent_for(config)
    stored = runner.delivered if policy == "best" else runner.sac
    params = jax.tree_util.tree_map(lambda x: x[0], stored.actor_params)
    expected = np.asarray(jax.jit(lambda params, key: sac_jax.evaluate(
        agent, env, params, key, 6))(params, jax.random.key(3)), np.float64)
    np.testing.assert_array_equal(result["ours"]["returns"], expected)
    assert result["ours"]["mean"] == pytest.approx(float(np.mean(expected)), rel=1e-15)
    assert "gymnasium" not in result


def test_paired_gymnasium_episodes_match_ours(run, capsys):
    result = _json(capsys, [run, "--episodes", "4", "--paired"])
    ours, gym = np.array(result["ours"]["returns"]), np.array(result["gymnasium"]["returns"])
    np.testing.assert_allclose(gym, ours, atol=PAIRED_TOLERANCE, rtol=0)
    assert result["max_abs_difference"] == pytest.approx(np.max(np.abs(ours - gym)))
    assert np.ptp(ours) > 10 * PAIRED_TOLERANCE  # the episodes differ: starts were really set


def test_gymnasium_with_its_own_initial_states_and_the_text_output(run, capsys):
    assert evaluate_script.main([run, "--episodes", "3", "--which", "gymnasium"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 2 and lines[1].startswith("gymnasium: ")
    assert lines[1].endswith("over 3 episodes") and " ± " in lines[1]
    returns = evaluate_script.gymnasium_returns(
        sac_jax.load_policy(run), gymnasium.make("Pendulum-v1"), 3, 0)
    assert lines[1] == f"gymnasium: {returns.mean():.1f} ± {returns.std():.1f} over 3 episodes"


def _fails(capsys, argv, code, message):
    fails_in_one_line(capsys, evaluate_script.main, argv, code, message)


def _bad_copy(run, tmp_path, damage):
    """A copy of `run` without its checkpoints (`damage` None) or with the newest damaged."""
    path = str(tmp_path / "copy")
    shutil.copytree(run, path)
    if damage is None:
        shutil.rmtree(run_checkpoint.directory(path))
    else:
        damage_checkpoint(path, damage)
    return path


def test_missing_run_directory(tmp_path, capsys):
    _fails(capsys, [str(tmp_path / "nowhere")], 2, "no such run directory")


def test_missing_checkpoint(run, tmp_path, capsys):
    _fails(capsys, [_bad_copy(run, tmp_path, None), "--which", "ours"], 2, "not found")


def test_bad_seed(run, capsys):
    _fails(capsys, [run, "--seed", "1"], 2, "seed=1: run")


@pytest.mark.parametrize("value", ["0", "-2", "many"])
def test_bad_episodes(run, capsys, value):
    _fails(capsys, [run, "--episodes", value], 2, "--episodes")


@pytest.mark.parametrize("value", ["-1", str(2 ** 32)])
def test_bad_episode_seed(run, capsys, value):
    _fails(capsys, [run, "--episode-seed", value], 2,
           f"--episode-seed={value}: must be an integer in [0, 2**32)")


def test_paired_needs_both(run, capsys):
    _fails(capsys, [run, "--which", "ours", "--paired"], 2, "--paired")


def test_gymnasium_missing(run, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "gymnasium", None)  # import gymnasium -> ImportError
    _fails(capsys, [run, "--which", "gymnasium"], 1, 'pip install "gymnasium[mujoco]"')
    _fails(capsys, [run], 1, 'pip install "gymnasium[mujoco]"')


def test_environment_without_a_gymnasium_twin(tmp_path, capsys):
    path = str(tmp_path / "bullet")
    run_dir.create(path, sac_jax.PRESETS["v1"], preset="v1", seeds=1, seed=0)
    assert sac_jax.PRESETS["v1"].env == "InvertedPendulumBullet-v0"
    assert "InvertedPendulumBullet-v0" in envs.registered()
    _fails(capsys, [path, "--which", "both"], 2,
           "InvertedPendulumBullet-v0 has no Gymnasium counterpart")
    _fails(capsys, [path, "--which", "gymnasium"], 2, "use --which ours")


def test_a_task_without_a_gymnasium_twin_is_evaluated_in_ours_by_default(tmp_path, capsys):
    path = untrained(str(tmp_path / "bullet"), "InvertedPendulumBullet-v0")
    assert evaluate_script.main([path, "--episodes", "2", "--json"]) == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert "ours" in result and "gymnasium" not in result


