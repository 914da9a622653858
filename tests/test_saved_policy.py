"""sac_jax.load_policy: the checkpoint's actor of the chosen seed as a numpy function, giving
exactly `Agent.act`'s deterministic actions; clear errors for a bad run directory, checkpoint,
seed or observation."""

import json
import os
import shutil

import jax
import numpy as np
import pytest

from flax import serialization

import sac_jax
from sac_jax import checkpoint, legacy_checkpoint, run, run_checkpoint, run_dir
from sac_jax.train import agent_for
from scripts import train as train_script
from tests.saved_runs import (damage_checkpoint, trained_pendulum, untrained,
                              with_planted_delivered_actor)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("runs")
    return {"trained": trained_pendulum(str(root / "pendulum")),
            "two_seeds": untrained(str(root / "two_seeds"), "Pendulum-v1", seeds=2)}


def _stored_actions(path, seed, obs, which="best"):
    """`Agent.act` (jitted, no key: deterministic) on the actor parameters of `seed` read
    straight from the checkpoint: the delivered actor's ("best") or the learner's ("last")."""
    config, _, runner, _ = run_checkpoint.load_checkpoint(path)
    agent, _ = agent_for(config)
    actor = runner.delivered.actor_params if which == "best" else runner.sac.actor_params
    params = jax.tree_util.tree_map(lambda x: x[seed], actor)
    return np.asarray(jax.jit(agent.act)(params, obs))


def _observations(n, seed=0):
    rng = np.random.default_rng(seed)
    theta = rng.uniform(-np.pi, np.pi, n)
    return np.stack([np.cos(theta), np.sin(theta), rng.uniform(-8, 8, n)], 1).astype(np.float32)


def test_actions_are_agent_act_on_the_stored_parameters(runs):
    policy = sac_jax.load_policy(runs["trained"])
    obs = _observations(16)
    actions = policy(obs)
    assert actions.shape == (16, 1) and actions.dtype == np.float32
    np.testing.assert_array_equal(actions, _stored_actions(runs["trained"], 0, obs))
    single = policy(obs[3].astype(np.float64))  # any real dtype; one observation
    assert single.shape == (1,)
    np.testing.assert_array_equal(single, _stored_actions(runs["trained"], 0, obs[3]))
    assert np.all(np.abs(actions) <= 2.0) and np.ptp(actions) > 0  # Pendulum's torque bound


def test_the_delivered_actor_by_default_the_last_one_on_request(tmp_path, runs):
    """In a copy of the trained run, the delivered actor is planted as half the learner's
    parameters, so the two policies differ; each loads its own."""
    path = str(tmp_path / "planted")
    shutil.copytree(runs["trained"], path)
    with_planted_delivered_actor(path)
    obs = _observations(16)
    best, last = (sac_jax.load_policy(path, which=w) for w in ("best", "last"))
    assert (best.which, last.which) == ("best", "last")
    np.testing.assert_array_equal(best(obs), _stored_actions(path, 0, obs, "best"))
    np.testing.assert_array_equal(last(obs), _stored_actions(path, 0, obs, "last"))
    np.testing.assert_array_equal(sac_jax.load_policy(path)(obs), best(obs))
    assert not np.allclose(best(obs), last(obs))
    with pytest.raises(ValueError, match="which='first': must be 'best' or 'last'"):
        sac_jax.load_policy(path, which="first")


def _as_msgpack_run(path, runner, position, format):
    """Turns the run directory `path` into one of an earlier sac-jax: its state `runner` in a
    msgpack checkpoint of `format` (2: without the delivered actor and stop flags)."""
    # the state of layout 1 (no evaluations under way here); earlier sac-jax kept no
    # non-finite record
    runner = run_checkpoint._stored_as(runner, 1).replace(non_finite=None)
    if format == 2:
        runner = runner.replace(delivered=None, stopped=None)
    leaves, filled = run_checkpoint._stored(runner)
    payload = {"format": format, "meta": {"position": position.to_json(), "buffer_filled": filled},
               "leaves": {str(i): x for i, x in enumerate(leaves)}}
    with open(os.path.join(path, legacy_checkpoint.FILE), "wb") as f:
        f.write(serialization.msgpack_serialize(payload))
    shutil.rmtree(run_checkpoint.directory(path))


def test_a_run_of_an_earlier_sac_jax_loads_its_delivered_actor(tmp_path, runs):
    """A msgpack checkpoint of format 3 (before orbax) delivers the same policy."""
    old = str(tmp_path / "old")
    shutil.copytree(runs["trained"], old)
    _, _, runner, position = run_checkpoint.load_checkpoint(old)
    _as_msgpack_run(old, runner, position, format=3)
    obs = _observations(8)
    np.testing.assert_array_equal(sac_jax.load_policy(old)(obs),
                                  sac_jax.load_policy(runs["trained"])(obs))


def test_a_run_without_a_delivered_actor_delivers_its_last_actor_with_a_warning(tmp_path, runs):
    """A format-2 checkpoint (the state without the delivered actor and stop flags) loads its
    last actor and says so; resuming it is refused in one line."""
    old = str(tmp_path / "old")
    shutil.copytree(runs["trained"], old)
    _, _, runner, position = run_checkpoint.load_checkpoint(old)
    _as_msgpack_run(old, runner, position, format=2)
    with pytest.warns(UserWarning, match="earlier sac-jax, which kept no delivered policy"):
        policy = sac_jax.load_policy(old)
    obs = _observations(4)
    assert policy.which == "last"
    np.testing.assert_array_equal(policy(obs), _stored_actions(runs["trained"], 0, obs, "last"))
    with pytest.raises(checkpoint.CheckpointError, match="format 2.*cannot be resumed"):
        run_checkpoint.load_checkpoint(old)


LAYOUT_1 = os.path.join(os.path.dirname(__file__), "data", "layout1-alongside")
"""A run directory of layout 1 (`run_checkpoint.LAYOUT`), written by sac-jax at 574701d:
`python scripts/train.py --preset pendulum --num-envs 4 --total-steps 2200 --learning-starts
1000 --eval-every 300 --eval-episodes 2 --confirm-episodes 2 --actor-hidden 8 8 --critic-hidden
8 8 --buffer-size 2200 --eval-alongside` (D = 3), its checkpoints of steps 1300 (evaluations
under way) and 2200 (the end), config.json, run.json and summary.json."""


def test_a_run_of_layout_1_delivers_its_actor_and_resumes(tmp_path):
    """Its delivered actor and score load as the run wrote them (its score one measurement, no
    kept actor's returns), and a resume from the checkpoint with evaluations under way finishes
    the run in the current layout."""
    summary = json.load(open(os.path.join(LAYOUT_1, "summary.json")))
    _, _, runner, _ = run_checkpoint.load_checkpoint(LAYOUT_1)
    np.testing.assert_allclose(runner.delivered.score, summary["delivered_return"], rtol=1e-6)
    assert list(runner.delivered.env_steps) == summary["delivered_at_step"]
    assert list(runner.delivered.count) == [1]
    assert np.isnan(runner.outputs["kept_return"]).all()
    policy = sac_jax.load_policy(LAYOUT_1)
    np.testing.assert_array_equal(policy(_observations(4)), np.asarray(
        agent_for(policy.config)[0].act(jax.tree_util.tree_map(
            lambda x: x[0], runner.delivered.actor_params), _observations(4))))
    _, _, mid, _ = run_checkpoint.load_checkpoint(LAYOUT_1, step=1300)
    assert mid.pending.active.any() and (mid.pending.kept_steps == -2).all()
    run = str(tmp_path / "run")
    shutil.copytree(LAYOUT_1, run)
    shutil.rmtree(os.path.join(run, run_checkpoint.CHECKPOINTS, "2200"))
    os.remove(os.path.join(run, "summary.json"))
    assert train_script.main(["--resume", run]) == 0
    resumed = json.load(open(os.path.join(run, "summary.json")))
    assert resumed["status"] == "finished" and np.isfinite(resumed["delivered_return"]).all()
    newest = run_checkpoint.saved_steps(run)[-1]
    header = json.load(open(os.path.join(run_checkpoint.directory(run), str(newest), "meta",
                                         "metadata")))
    assert newest == 2200 and header["meta"]["layout"] == run_checkpoint.LAYOUT


LAYOUT_2 = os.path.join(os.path.dirname(__file__), "data", "layout2-stopped")
"""A run directory of layout 2, written by sac-jax at da956be, whose seed 0 stopped on its
first confirmation: `python scripts/train.py --preset pendulum --num-envs 4 --total-steps 2200
--learning-starts 1000 --eval-every 300 --eval-episodes 2 --confirm-episodes 2 --actor-hidden 8
8 --critic-hidden 8 8 --buffer-size 2200 --seeds 2 --stop-when-solved --stop-return -1340`,
its checkpoint of step 2200, config.json, run.json and summary.json."""


def test_a_run_of_layout_2_keeps_its_stop_rule_and_stopped_seeds():
    """Its config reads with the rule it ran under (stop on one measurement), and its
    `stopped` output is rebuilt from its kept scores, agreeing with its seeds' flags."""
    summary = json.load(open(os.path.join(LAYOUT_2, "summary.json")))
    config, _, runner, _ = run_checkpoint.load_checkpoint(LAYOUT_2)
    assert config.stop_measurements == 1 and summary["stopped"] == [True, False]
    assert list(runner.stopped) == summary["stopped"]
    np.testing.assert_array_equal(runner.outputs["stopped"], [[1.0] * 4, [0.0] * 4])
    assert [means["stopped"] for _, means, _ in run.evaluation_points(config, runner)] == [0.5] * 4
    policy = sac_jax.load_policy(LAYOUT_2)
    np.testing.assert_array_equal(policy(_observations(4)), np.asarray(
        agent_for(policy.config)[0].act(jax.tree_util.tree_map(
            lambda x: x[0], runner.delivered.actor_params), _observations(4))))


def test_seed_selects_that_seeds_actor(runs):
    obs = _observations(8, seed=1)
    first, second = (sac_jax.load_policy(runs["two_seeds"], seed=s) for s in (0, 1))
    np.testing.assert_array_equal(second(obs), _stored_actions(runs["two_seeds"], 1, obs))
    assert not np.allclose(first(obs), second(obs))
    assert (second.seed, second.info.seeds, second.config.env) == (1, 2, "Pendulum-v1")


@pytest.mark.parametrize("seed", [-1, 2, 1.0, True, "0"])
def test_a_seed_the_run_does_not_have_is_refused(runs, seed):
    with pytest.raises(ValueError, match=rf"seed={seed!r}: run .* has seeds 0\.\.1"):
        sac_jax.load_policy(runs["two_seeds"], seed=seed)


@pytest.mark.parametrize("shape", [(4,), (2, 2), (2, 3, 3), ()])
def test_an_observation_of_the_wrong_shape_is_refused(runs, shape):
    policy = sac_jax.load_policy(runs["two_seeds"])
    with pytest.raises(ValueError, match=r"expected \(3,\) or \(batch, 3\) for Pendulum-v1"):
        policy(np.zeros(shape))


def _run_without_checkpoint(path):
    run_dir.create(str(path), sac_jax.PRESETS["pendulum"], preset="pendulum", seeds=1, seed=0)
    return str(path)


def test_missing_run_directory_and_checkpoint(tmp_path):
    with pytest.raises(run_dir.RunDirError, match="no such run directory"):
        sac_jax.load_policy(str(tmp_path / "nowhere"))
    with pytest.raises(checkpoint.CheckpointError, match="not found"):
        sac_jax.load_policy(_run_without_checkpoint(tmp_path / "empty"))


@pytest.mark.parametrize("how, message", [("garbage", "unreadable"),
                                          ("truncate", "unreadable|damaged"),
                                          ("flip", "damaged")])
def test_damaged_checkpoints(tmp_path, runs, how, message):
    path = str(tmp_path / how)
    shutil.copytree(runs["trained"], path)
    damage_checkpoint(path, how)
    with pytest.raises(checkpoint.CheckpointError, match=message):
        sac_jax.load_policy(path)
