"""The delivered policy (`sac_jax.selection`): the kept actor is the one with the best confirmed
evaluation, checked with planted evaluation values and in the training loop; with
`stop_when_solved` a solved seed's learner and kept actor no longer change, and a run whose
seeds have all stopped ends."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import envs
import sac_jax
from sac_jax import run, selection
from sac_jax.train import make_train_parts

# Pendulum-v1 with small networks: 4 evaluation points, 1 seed (compiles in seconds)
CONFIG = sac_jax.PRESETS["pendulum"].replace(
    total_steps=1280, learning_starts=256, eval_every=256, batch_size=32, num_envs=2,
    actor_hidden=(16, 16), critic_hidden=(16, 16), eval_episodes=1, confirm_episodes=2)


def _planted(points):
    """Runs `select` over planted points (evaluation s, confirmation c, actor id); returns the
    kept (actor id, score, step) after each point and the confirmations it reported."""
    step = jax.jit(lambda kept, actor, s, c, steps: selection.select(
        kept, actor, s, c, steps))
    kept = selection.init(jnp.float32(-1.0))
    history, reported = [], []
    for p, (s, c, actor) in enumerate(points):
        kept, confirmed = step(kept, jnp.float32(actor), jnp.float32(s), jnp.float32(c),
                               jnp.int32(1000 * (p + 1)))
        history.append((float(kept.actor_params), float(kept.score), int(kept.env_steps)))
        reported.append(float(confirmed))
    return history, reported


def test_a_candidate_replaces_the_kept_actor_only_when_its_confirmation_is_higher():
    history, reported = _planted([
        (100.0, 90.0, 0),     # first point: kept with its confirmed 90
        (80.0, 500.0, 1),     # not a candidate (80 <= 90): its high confirmation is never used
        (1000.0, 50.0, 2),    # lucky evaluation, confirmed lower than 90: kept stays
        (95.0, 95.0, 3),      # candidate, confirmed 95 > 90: replaces
        (1000.0, 95.0, 4),    # confirmed 95, a tie: the older actor stays
        (1000.0, 1000.0, 5),  # replaces
        (1000.0, 1000.0, 6),  # s = 1000 is no longer above the kept score: not a candidate
    ])
    assert history == [(0, 90, 1000), (0, 90, 1000), (0, 90, 1000), (3, 95, 4000),
                       (3, 95, 4000), (5, 1000, 6000), (5, 1000, 6000)]
    assert np.isnan(reported[1]) and np.isnan(reported[6])
    assert reported[2] == 50.0 and reported[4] == 95.0


def test_before_any_point_nothing_is_selected():
    kept = selection.init({"w": jnp.ones(3)})
    assert float(kept.score) == -np.inf and int(kept.env_steps) == -1


def _points_of_a_run(config, seeds=2):
    """(learner actors at each evaluation point, final runner, outputs) of `config` run chunk
    by chunk, seeds vmapped."""
    parts = make_train_parts(config)
    axes = sac_jax.train.SEED_AXES
    init = jax.jit(jax.vmap(parts.init, out_axes=axes))
    chunk = jax.jit(jax.vmap(parts.chunk, in_axes=(axes,), out_axes=axes))
    runner = init(jax.random.split(jax.random.key(7), seeds))
    actors = {}
    for _ in range(parts.num_chunks):
        before = int(runner.iteration)
        runner = chunk(runner)
        if int(runner.iteration) > config.prefill_iterations and (
                int(runner.iteration) - config.prefill_iterations) % config.iterations_per_eval == 0:
            steps = int(runner.iteration) * config.num_envs
            actors[steps] = jax.device_get(runner.sac.actor_params)
        assert int(runner.iteration) > before
    return actors, runner, jax.device_get(runner.outputs)


def test_the_loop_delivers_the_actor_of_its_best_confirmed_point():
    """For each seed: the delivered return is the running maximum of the confirmed returns,
    a confirmation ran exactly where the evaluation beat the kept score, and the delivered
    actor is, bit for bit, the learner's actor at the point that set that maximum."""
    actors, runner, out = _points_of_a_run(CONFIG)
    for seed in range(2):
        confirm, delivered = out["confirm_return"][seed], out["delivered_return"][seed]
        evaluated = out["eval_return"][seed]
        previous = np.concatenate([[-np.inf], delivered[:-1]])
        np.testing.assert_array_equal(np.isnan(confirm), ~(evaluated > previous))
        np.testing.assert_array_equal(
            delivered, np.maximum.accumulate(np.where(np.isnan(confirm), -np.inf, confirm)))
        best = int(np.argmax(delivered == delivered[-1]))  # the point that set it first
        step = int(out["env_steps"][seed][best])
        assert int(runner.delivered.env_steps[seed]) == step
        assert float(runner.delivered.score[seed]) == delivered[-1]
        for kept, at_step in zip(jax.tree_util.tree_leaves(runner.delivered.actor_params),
                                 jax.tree_util.tree_leaves(actors[step])):
            np.testing.assert_array_equal(np.asarray(kept)[seed], at_step[seed])


@pytest.fixture
def solved_at_once(monkeypatch):
    """Pendulum-v1's solved return lowered below any return, so a seed is solved at its first
    evaluation point (the threshold is read when the loop is traced)."""
    spec = envs.spec("Pendulum-v1")
    monkeypatch.setitem(envs.registry.SPECS, spec.name,
                        dataclasses.replace(spec, solved_return=-1e9))
    return CONFIG.replace(stop_when_solved=True)


def test_a_solved_seed_no_longer_changes(solved_at_once):
    """make_train (which runs every chunk): after the first point the learner's parameters,
    optimiser states, temperature and delivered actor stay bit for bit, and no update metric
    is reported; the shared update counter keeps counting."""
    parts = make_train_parts(solved_at_once)
    init, chunk = jax.jit(parts.init), jax.jit(parts.chunk)
    runner = init(jax.random.key(3))
    while int(runner.iteration) <= solved_at_once.prefill_iterations + (
            solved_at_once.iterations_per_eval - 1):
        runner = chunk(runner)
    assert bool(runner.stopped)
    at_stop = jax.device_get(runner)
    while int(runner.iteration) < parts.num_iterations:
        runner = chunk(runner)
    end = jax.device_get(runner)
    for name in ("actor_params", "critic_params", "critic_target_params", "actor_opt_state",
                 "critic_opt_state", "alpha_opt_state", "log_alpha", "alpha"):
        for a, b in zip(jax.tree_util.tree_leaves(getattr(at_stop.sac, name)),
                        jax.tree_util.tree_leaves(getattr(end.sac, name))):
            np.testing.assert_array_equal(a, b, err_msg=name)
    for a, b in zip(jax.tree_util.tree_leaves(at_stop.delivered),
                    jax.tree_util.tree_leaves(end.delivered)):
        np.testing.assert_array_equal(a, b)
    assert int(end.sac.step) > int(at_stop.sac.step)
    assert np.all(np.isnan(end.outputs["critic_loss"][1:]))
    assert np.isfinite(end.outputs["critic_loss"][0])


def test_a_run_whose_seeds_have_all_stopped_ends(solved_at_once):
    result = run.run_training(solved_at_once, seeds=2)
    assert result.status == run.FINISHED and result.points == 1
    assert result.summary["stopped"] == [True, True]
    assert result.summary["solved_at_step"] == [512, 512]
    assert result.summary["delivered_at_step"] == [512, 512]
    assert result.summary["all_solved_wall_s"] == result.summary["solved_wall_s"][0]
    # without the option the same seeds train to the end
    assert run.run_training(CONFIG, seeds=2).points == CONFIG.num_evals
