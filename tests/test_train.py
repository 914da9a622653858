"""make_train on a small Pendulum-v1 run (pure JAX, quick to compile): output shapes and
values, determinism, vmap over seeds equal to separate runs, and the named scopes of the
iteration's parts."""

import jax
import jax.extend
import numpy as np
import pytest

import sac_jax
from sac_jax.train import make_train_parts
from tests.parallel_checks import LEARNER_BOUND, METRIC_ULPS

CONFIG = sac_jax.PRESETS["pendulum"].replace(
    total_steps=1024, learning_starts=256, eval_every=256, batch_size=64, num_envs=2,
    updates_per_step=2, actor_hidden=(32, 32), critic_hidden=(32, 32), eval_episodes=2)
KEYS = jax.random.split(jax.random.key(3), 2)


@pytest.fixture(scope="module")
def train():
    return jax.jit(sac_jax.make_train(CONFIG))


@pytest.fixture(scope="module")
def first(train):
    return jax.device_get(train(KEYS[0]))


def test_metrics_have_one_entry_per_evaluation(first):
    runner, metrics = first
    assert CONFIG.num_evals == 3
    np.testing.assert_array_equal(metrics["env_steps"], [512, 768, 1024])
    for name in ("eval_return", "critic_loss", "actor_loss", "alpha", "q"):
        assert metrics[name].shape == (3,) and np.all(np.isfinite(metrics[name])), name
    # Pendulum episodes are truncated at 200 steps: with 2 envs they end at iterations 200 and
    # 400, in the first and third evaluation periods (iterations 128-255, 256-383, 384-511);
    # a period in which no training episode ended reports NaN.
    np.testing.assert_array_equal(np.isfinite(metrics["train_return"]), [True, False, True])
    # a Pendulum reward lies in [-(pi^2 + 0.1 * 8^2 + 0.001 * 2^2), 0] ~ [-16.3, 0] per step
    assert np.all((metrics["train_return"][[0, 2]] <= 0) & (metrics["train_return"][[0, 2]] > -3300))
    assert np.all(np.isnan(metrics["value_loss"]))  # v2 has no value network
    # every iteration wrote num_envs transitions; 2 updates per training iteration
    assert int(runner.buffer.size) == 1024
    assert int(runner.sac.step) == (1024 - 256) // 2 * 2


def _comparable(result):
    """The run's metrics and learned state, without PRNG keys (not comparable as arrays)."""
    runner, metrics = result
    return metrics, runner.sac, runner.buffer


def test_same_key_gives_identical_results(train, first):
    again = jax.device_get(train(KEYS[0]))
    jax.tree_util.tree_map(np.testing.assert_array_equal, _comparable(first), _comparable(again))


def test_vmap_over_seeds_equals_separate_runs(float64_checks):
    """Two seeds in one vmapped program reproduce two separate runs of this module's CONFIG
    (768 updates). vmap batches the matmuls, whose rounding differs, and training amplifies it,
    so the comparison runs with the learner state in float64 (tests/parallel_checks.py, "separate",
    in the x64 subprocess shared with test_parallel.py): per-array relative difference of the
    learner states <= 1e-9 (float64's 2.2e-16 times the run's amplification of at most 1e5:
    `LEARNER_BOUND`), the float32 metrics within 512 float32 ulps of their largest magnitude
    (one ulp for each rounding on their path: `METRIC_ULPS`). Measured:
    1.2e-14 and bit-identical. The two seeds' actor parameters differ by more than 30% of their
    scale, and their critic losses by more than 2%."""
    check = float64_checks["separate"]
    assert check["learner_dtypes"] == ["float64"], check
    assert max(check["learner_rel_diff"]) <= LEARNER_BOUND, check
    assert max(check["metrics_ulps"]) <= METRIC_ULPS, check
    assert check["seeds_rel_diff"] > 0.3, check
    assert check["seeds_critic_loss_rel_diff"] > 2e-2, check


def test_a_sweep_equals_separate_runs_of_its_settings(float64_checks):
    """2 settings (actor_lr, critic_lr and gamma changed) x 2 seeds traced in one vmapped
    program reproduce the 4 separate runs of each setting's own config on the same keys
    (tests/parallel_checks.py, "settings", float64 learners as above): the same bounds,
    `LEARNER_BOUND` and `METRIC_ULPS`. Measured: 2.4e-14 and bit-identical metrics. The
    settings' actors differ by more than their scale, so a setting that was not applied fails."""
    check = float64_checks["settings"]
    assert check["swept"] == ["actor_lr", "critic_lr", "gamma"], check
    assert check["learner_dtypes"] == ["float64"], check
    assert len(check["learner_rel_diff"]) == 4, check
    assert max(check["learner_rel_diff"]) <= LEARNER_BOUND, check
    assert max(check["metrics_ulps"]) <= METRIC_ULPS, check
    assert check["settings_rel_diff"] > 0.3, check


def test_hyperparams_stack_refuses_configs_of_different_programs():
    """Settings that change a shape cannot share one program: one line naming the rule."""
    with pytest.raises(ValueError,
                       match=r"^stack: configs\[1\].batch_size=32 differs from "
                             r"configs\[0\]'s 64; "):
        sac_jax.hyperparams.stack([CONFIG, CONFIG.replace(batch_size=32)])
    with pytest.raises(ValueError, match="no configs"):
        sac_jax.hyperparams.stack([])
    assert sac_jax.hyperparams.stack([CONFIG, CONFIG]) == {}


def _max_diff_and_scale(a, b):
    """(max |a - b|, max |b|) over all leaves of two parameter pytrees."""
    pairs = zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b))
    return tuple(np.max([(np.abs(x - y).max(), np.abs(y).max()) for x, y in pairs], axis=0))


def test_replay_buffer_is_updated_in_place_inside_the_loop():
    """The compiled loop writes the buffer in place: no buffer-sized copy inside any loop body
    (one at program entry, from the zero initialisation, is fine). A copy there would cost
    O(capacity) per iteration; it happened with nested scans before the loop was flattened."""
    import re

    capacity = 77_778  # an unmistakable leading dimension
    config = CONFIG.replace(buffer_size=capacity)
    text = jax.jit(sac_jax.make_train(config)).lower(KEYS[0]).compile().as_text()
    computation, copies = None, []
    for line in text.splitlines():
        if line and not line.startswith(" ") and "{" in line:
            computation = line.split(" ")[0]
        if re.search(rf"= \w+\[{capacity}[,\]]", line) and " copy(" in line:
            copies.append(computation)
    assert all(c == "ENTRY" for c in copies), copies


def test_chunks_of_at_most_max_iterations_end_on_the_boundaries_and_give_the_run(first):
    """`advance(runner, max_iterations)` stops at the next boundary or after `max_iterations`
    iterations, whichever comes first, also where its fixed-length blocks (gcd(prefill,
    period, max_iterations) = 16 iterations here) are shorter than the chunk, and the chunks
    make the run of `train` (the module's first run)."""
    parts = make_train_parts(CONFIG)
    advance = jax.jit(lambda runner: parts.advance(runner, max_iterations=48))
    evaluate = jax.jit(parts.evaluate)
    runner, ends = parts.init(KEYS[0]), []
    while int(runner.iteration) < parts.num_iterations:
        runner = evaluate(advance(runner))
        ends.append(int(runner.iteration))
    # prefill 128 iterations (256 steps of 2 envs), then a point every 128
    assert ends == [48, 96, 128, 176, 224, 256, 304, 352, 384, 432, 480, 512]
    chunked = _comparable(jax.device_get((runner, runner.outputs)))
    jax.tree_util.tree_map(np.testing.assert_array_equal, chunked, _comparable(first))


def test_replaying_the_recorded_draws_reproduces_the_run(first):
    """`make_train(config, randomness=replay(config, record_draws(config, key)))(key)` takes
    every random draw of acting and learning from the stream and gives the run of `train(key)`
    bit for bit (evaluations included, whose keys come from the same chain), so the stream is
    exactly what the loop draws."""
    draws = jax.jit(sac_jax.record_draws, static_argnums=0)(CONFIG, KEYS[0])
    iterations = CONFIG.prefill_iterations + CONFIG.num_evals * CONFIG.iterations_per_eval
    assert draws.batch_index.shape == (iterations, CONFIG.updates_per_step, CONFIG.batch_size)

    def replayed(draws):
        train = sac_jax.make_train(CONFIG, randomness=sac_jax.replay(CONFIG, draws))
        return jax.device_get(jax.jit(train)(KEYS[0]))

    jax.tree_util.tree_map(np.testing.assert_array_equal, _comparable(first),
                           _comparable(replayed(draws)))
    # and the stream is what the loop uses: other policy noise gives another run
    changed = replayed(draws.replace(action_noise=-draws.action_noise))
    diff, _ = _max_diff_and_scale(changed[0].sac.actor_params, first[0].sac.actor_params)
    assert diff > 0, diff


def test_a_stream_of_the_wrong_shape_is_refused():
    draws = jax.eval_shape(lambda key: sac_jax.record_draws(CONFIG, key), KEYS[0])
    short = draws.replace(batch_index=jax.ShapeDtypeStruct((5, 2, 64), np.int32))
    with pytest.raises(ValueError, match=r"draws\.batch_index has shape \(5, 2, 64\)"):
        sac_jax.replay(CONFIG, short)
    floats = draws.replace(batch_index=jax.ShapeDtypeStruct(draws.batch_index.shape, np.float32))
    with pytest.raises(ValueError, match="batch_index"):
        sac_jax.replay(CONFIG, floats)


def test_the_iterations_parts_carry_the_named_scopes_profiles_sum_by():
    """benchmarks/profile_chunk.py attributes a chunk's kernels to the named scopes of its
    parts; each must name some of the traced chunk's operations."""
    from benchmarks.profile_chunk import PARTS
    from sac_jax.train import make_train_parts

    parts = make_train_parts(CONFIG)
    jaxpr = jax.make_jaxpr(parts.chunk)(jax.eval_shape(parts.init, KEYS[0]))

    def scopes(jaxpr):
        for eqn in jaxpr.eqns:
            yield from str(eqn.source_info.name_stack).split("/")
            for sub in jax.extend.core.jaxprs_in_params(eqn.params):
                yield from scopes(sub)

    assert set(PARTS) <= set(scopes(jaxpr.jaxpr))


def test_hyperparams_sweep_refuses_a_value_that_is_not_a_list():
    with pytest.raises(ValueError, match=r"^settings: actor_lr=0\.001: expected a list of values$"):
        sac_jax.hyperparams.sweep(CONFIG, {"actor_lr": 1e-3}, 2)
    assert sac_jax.hyperparams.setting_of(sac_jax.hyperparams.run_index(2, 1, 3), 3) == 2
