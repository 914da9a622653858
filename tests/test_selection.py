"""The delivered policy (`sac_jax.selection`): a candidate replaces the kept actor only by
beating it on the same confirmation episodes, and the kept score is the mean of the kept
actor's measurements, checked with planted evaluation values and in the training loop; with
`stop_when_solved` a seed stops once its kept score, solved, averages `stop_measurements`
measurements, a stopped seed's learner and kept actor no longer change, and a run whose seeds
have all stopped ends."""

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
    """Runs `select` over planted points (evaluation s, confirmation c, kept actor's return k,
    whether k is the kept actor's, actor id); returns the kept (actor id, score, count, step)
    after each point and the confirmations and kept returns it reported."""
    step = jax.jit(selection.select)
    kept = selection.init(jnp.float32(-1.0))
    history, reported = [], []
    for p, (s, c, k, paired, actor) in enumerate(points):
        kept, confirmed, kept_return = step(
            kept, jnp.float32(actor), jnp.float32(s), jnp.float32(c), jnp.float32(k),
            jnp.bool_(paired), jnp.int32(1000 * (p + 1)))
        history.append((float(kept.actor_params), float(kept.score), int(kept.count),
                        int(kept.env_steps)))
        reported.append((float(confirmed), float(kept_return)))
    return history, reported


def test_a_candidate_replaces_the_kept_actor_only_when_it_beats_it_on_the_same_episodes():
    history, reported = _planted([
        (100.0, 90.0, 7.0, True, 0),    # first point: kept with its confirmed 90 (k unused)
        (80.0, 500.0, 70.0, True, 1),   # no candidate (80 <= 90): c unused; c* <- (90 + 70) / 2
        (1000.0, 50.0, 60.0, True, 2),  # lucky evaluation, 50 < k = 60: c* <- (160 + 60) / 3
        (95.0, 65.0, 60.0, True, 3),    # candidate, beats the kept actor on its episodes
        (1000.0, 70.0, 70.0, True, 4),  # a tie: the older actor stays, c* <- (65 + 70) / 2
        (1000.0, 99.0, 9.0, False, 5),   # k is not the kept actor's: neither used nor beaten
        (1000.0, 68.0, 60.0, True, 6),   # replaces
        (60.0, 1.0, 2.0, True, 7),       # no candidate: c* <- (68 + 2) / 2
    ])
    np.testing.assert_allclose(history, [
        (0, 90, 1, 1000), (0, 80, 2, 1000), (0, 220 / 3, 3, 1000), (3, 65, 1, 4000),
        (3, 67.5, 2, 4000), (3, 67.5, 2, 4000), (6, 68, 1, 7000), (6, 35, 2, 7000)], rtol=1e-6)
    confirmed, kept = np.array(reported).T
    assert np.isnan(confirmed[[1, 7]]).all() and confirmed[2] == 50.0 and confirmed[4] == 70.0
    np.testing.assert_array_equal(np.isnan(kept), [True, False, False, False, False, True,
                                                   False, False])


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
    # key 5: in both seeds some point replaces the kept actor and some re-measures it
    runner = init(jax.random.split(jax.random.key(5), seeds))
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


def replay_selection(out):
    """The kept scores `selection.select` gives on a run's reported returns, point by point
    (the kept actor's return counts where reported), the index of the point whose actor is
    kept after each point (-1 before any), and the number of measurements the score averages."""
    step = jax.jit(selection.select)
    kept = selection.init(jnp.int32(-1))
    scores, points, counts = [], [], []
    for p, (s, c, k) in enumerate(zip(out["eval_return"], out["confirm_return"],
                                      out["kept_return"])):
        paired = not np.isnan(k) or int(kept.count) == 0  # (nothing kept: always paired)
        kept = step(kept, jnp.int32(p), s, c, k, jnp.bool_(paired), jnp.int32(p))[0]
        scores.append(float(kept.score))
        points.append(int(kept.actor_params))
        counts.append(int(kept.count))
    return np.array(scores, np.float32), np.array(points), np.array(counts)


def test_the_loop_delivers_the_actor_its_selection_keeps():
    """For each seed: a confirmation ran exactly where the evaluation beat the kept score, the
    kept actor was measured at every point after the first, the delivered return follows the
    selection's rules on the reported returns (some point of the run replaced the kept actor,
    some re-measured it), and the delivered actor is, bit for bit, the learner's actor at the point
    the rules keep."""
    actors, runner, out = _points_of_a_run(CONFIG)
    kept_points = []
    for seed in range(2):
        mine = {name: values[seed] for name, values in out.items()}
        delivered = mine["delivered_return"]
        previous = np.concatenate([[-np.inf], delivered[:-1]])
        np.testing.assert_array_equal(np.isnan(mine["confirm_return"]),
                                      ~(mine["eval_return"] > previous))
        assert np.isnan(mine["kept_return"][0]) and np.isfinite(mine["kept_return"][1:]).all()
        scores, points, _ = replay_selection(mine)
        np.testing.assert_array_equal(delivered, scores)
        kept_points.append(points)
        step = int(mine["env_steps"][points[-1]])
        assert int(runner.delivered.env_steps[seed]) == step
        assert float(runner.delivered.score[seed]) == delivered[-1]
        for kept, at_step in zip(jax.tree_util.tree_leaves(runner.delivered.actor_params),
                                 jax.tree_util.tree_leaves(actors[step])):
            np.testing.assert_array_equal(np.asarray(kept)[seed], at_step[seed])
    kept_points = np.array(kept_points)  # a replacement and a re-measurement both happened
    assert np.any(kept_points[:, 1:] != kept_points[:, :-1])
    assert np.any(kept_points[:, 1:] == kept_points[:, :-1])


@pytest.fixture
def solved_everywhere(monkeypatch):
    """A stop below any return, so a seed is solved from its first evaluation point on. The
    compiled loop reads it from the config (`stop_return`), which names its programs in the
    persistent caches; the host's solved figures read Pendulum-v1's solved return, lowered
    alike. (Lowering only the latter once left a program stopping at -1e9 in the caches under
    the unchanged config's name, for the next run of that config.)"""
    spec = envs.spec("Pendulum-v1")
    monkeypatch.setitem(envs.registry.SPECS, spec.name,
                        dataclasses.replace(spec, solved_return=-1e9))
    return CONFIG.replace(stop_when_solved=True, stop_return=-1e9)


@pytest.fixture
def solved_at_once(solved_everywhere):
    """A seed stops at its first evaluation point, on its first confirmation."""
    return solved_everywhere.replace(stop_measurements=1)


@pytest.mark.parametrize("measurements", [1, 2, 3])
def test_a_seed_stops_once_its_kept_score_averages_enough_measurements(solved_everywhere,
                                                                       measurements):
    """Each seed stops (its `stopped` output turns 1 and stays) at the first point where the
    selection's replay on its reported returns counts `stop_measurements` measurements of
    the kept actor, and its delivered score stays as it was there; with 2 or more some seed
    learned on after its first confirmation."""
    config = solved_everywhere.replace(stop_measurements=measurements)
    _, _, out = _points_of_a_run(config)
    firsts = []
    for seed in range(2):
        mine = {name: values[seed] for name, values in out.items()}
        scores, _, counts = replay_selection(mine)
        first = int(np.argmax(counts >= measurements)) if np.any(counts >= measurements) else None
        at = len(counts) if first is None else first
        np.testing.assert_array_equal(mine["stopped"], np.arange(len(counts)) >= at)
        np.testing.assert_array_equal(mine["delivered_return"][:at + 1], scores[:at + 1])
        if first is not None:
            assert (mine["delivered_return"][first:] == scores[first]).all()
        firsts.append(first)
    assert (firsts == [0, 0]) == (measurements == 1), firsts


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
