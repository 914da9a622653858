"""sac_jax.run: once `compiled_program` has compiled a configuration, a run compiles nothing
more between its chunks (the finiteness check included), each evaluation point reports the
fraction of seeds solved so far, and a non-finite state is named by quantity and seed."""

import builtins
import dataclasses
import gc
import logging
import threading
import time
import uuid

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import envs

import sac_jax
from sac_jax import background, run, train

# shapes of its own (hidden 24), so no other test in the process has compiled this check
CONFIG = sac_jax.PRESETS["pendulum"].replace(
    total_steps=768, learning_starts=256, eval_every=256, batch_size=32, num_envs=2,
    actor_hidden=(24, 24), critic_hidden=(24, 24), eval_episodes=1)


def test_a_run_compiles_nothing_between_its_chunks(caplog):
    """Nothing is compiled at a chunk's end, while the device waits (a finiteness check
    compiled there once cost 0.36 s of the run on the CPU)."""
    run.compiled_program(CONFIG, 2)
    with jax.log_compiles(True), caplog.at_level(logging.WARNING):
        result = run.run_training(CONFIG, seeds=2)
    assert result.status == run.FINISHED and result.points == CONFIG.num_evals
    compiled = [r.getMessage() for r in caplog.records if "ompil" in r.getMessage()]
    # only the split of the seeds' keys, before the clock of the run starts
    assert all("split" in m for m in compiled), compiled


def test_each_point_reports_the_fraction_of_seeds_solved_so_far(monkeypatch):
    """means["solved"] at point p: the seeds whose delivered actor's confirmed return has
    reached the threshold, with a threshold between the returns this run reaches."""
    returns = run.run_training(CONFIG, seeds=2).metrics["delivered_return"]  # (seeds, points)
    threshold = float(np.median(returns))
    spec = envs.spec(CONFIG.env)
    monkeypatch.setitem(envs.registry.SPECS, spec.name,
                        dataclasses.replace(spec, solved_return=threshold))
    reported = []
    result = run.run_training(CONFIG, seeds=2,
                              on_point=lambda step, means, *_: reported.append(means["solved"]))
    np.testing.assert_array_equal(result.metrics["delivered_return"], returns)
    expected = np.mean(returns >= threshold, axis=0)
    assert 0.0 < expected[-1] and expected[0] < 1.0  # the check can tell counts apart
    np.testing.assert_array_equal(reported, expected)


@pytest.mark.parametrize("returns, expected", [
    ([900, 1000, 1000, 1000], 2000),   # reached at the second point and kept
    ([1000, 980, 1000, 1000], 3000),   # a re-measurement lowered it: solved from the third
    ([1000, 1000, 1000, 990], None),   # not solved at the end
    ([1000, np.nan, 1000, 1000], 3000),  # NaN counts as not solved
])
def test_solved_at_is_where_the_returns_stay_at_the_threshold(returns, expected):
    steps = np.array([1000, 2000, 3000, 4000])
    assert run.solved_at(np.array(returns, np.float32), steps, 1000.0) == expected


def test_the_first_non_finite_array_is_named_with_its_seed():
    _, init, _, _ = run.compiled_program(CONFIG, 2)
    sac = init(*run.start_args(0, 2)).sac
    flags = run._finite_flags
    assert run.first_non_finite(flags(sac)) is None
    bad = sac.replace(log_alpha=sac.log_alpha.at[1].set(jnp.nan))
    assert run.first_non_finite(flags(bad)) == "log_alpha of seed 1"
    both = bad.replace(critic_params=jax.tree_util.tree_map(lambda x: x.at[1].set(jnp.inf),
                                                            bad.critic_params))
    assert run.first_non_finite(flags(both)).startswith("critic_params/")  # state order
    # the field that went non-finite first, as the run recorded it
    assert run.first_non_finite(flags(both), [None, "log_alpha"]) == "log_alpha of seed 1"


def test_a_set_code_names_the_array_or_else_its_field():
    _, init, _, _ = run.compiled_program(CONFIG, 2)
    sac = init(*run.start_args(0, 2)).sac
    fields = train.non_finite_fields(CONFIG)
    code = np.array([0, fields.index("log_alpha") + 1])
    bad = sac.replace(log_alpha=sac.log_alpha.at[1].set(jnp.nan))
    assert run.non_finite_name(bad, code, fields) == "log_alpha of seed 1"
    # a NaN the next updates overwrote: the code still names the field
    assert run.non_finite_name(sac, code, fields) == "log_alpha of seed 1"
    assert run.non_finite_name(sac, np.array([1, 0]), fields) == f"{fields[0]} of seed 0"


def test_the_field_that_goes_non_finite_first_is_recorded_in_update_order():
    """`RunnerState.non_finite` names, of the fields an update writes, the first (in the
    update's order) holding a NaN after the first update that made any non-finite."""
    fields = train.non_finite_fields(CONFIG)
    assert fields[:2] == ("critic_params", "critic_opt_state") and "actor_params" in fields
    one = train.agent_for(CONFIG)[0].init(jax.random.key(0))
    nan = lambda tree: jax.tree_util.tree_map(lambda x: jnp.full_like(x, jnp.nan), tree)
    assert int(train._non_finite_code(one, fields)) == 0
    both = one.replace(actor_params=nan(one.actor_params), critic_params=nan(one.critic_params))
    assert fields[int(train._non_finite_code(both, fields)) - 1] == "critic_params"
    actor = one.replace(actor_params=nan(one.actor_params))
    assert fields[int(train._non_finite_code(actor, fields)) - 1] == "actor_params"


def test_a_sweep_trains_on_past_a_setting_that_diverges():
    """With `stop_on_non_finite=False` (scripts/sweep.py), a setting whose state becomes
    non-finite (critic learning rate 1e30) is reported per seed, and the other setting's seeds
    train to the end (that a setting trains as its own config's run does is tests/test_train.py's
    float64 check); without the option the run stops, naming the first seed of that setting."""
    settings = {"critic_lr": [CONFIG.critic_lr, 1e30]}
    result = run.run_training(CONFIG, seeds=2, settings=settings, stop_on_non_finite=False)
    assert result.status == run.FINISHED and result.points == CONFIG.num_evals
    at = result.summary["non_finite_at_step"]
    assert at[:2] == [None, None] and all(isinstance(s, int) and s > 0 for s in at[2:]), at
    assert np.isfinite(result.metrics["eval_return"][:2]).all()
    assert np.isfinite(result.metrics["delivered_return"]).all()  # kept from before
    stopped = run.run_training(CONFIG, seeds=2, settings=settings)
    assert stopped.status == run.NON_FINITE and "seed 2" in stopped.message, stopped.message


def test_a_stop_the_device_does_not_answer_in_time_leaves_the_chunk():
    """The host polls while the device works, so a stop is seen during a chunk: within the
    grace period the chunk is waited for and the run ends INTERRUPTED after it; past it
    (here 0 s), `DeviceBusy` is raised without waiting (scripts/train.py then exits with one
    line). A chunk of 2,048 iterations takes far longer than one poll."""
    import pytest

    config = CONFIG.replace(learning_starts=2048, eval_every=2048, total_steps=4096,
                            num_envs=1)
    result = run.run_training(config, should_stop=lambda: True)
    assert result.status == run.INTERRUPTED and result.position.chunks_done == 1
    with pytest.raises(run.DeviceBusy, match="still running a chunk 0 s after the stop"):
        run.run_training(config, should_stop=lambda: True, stop_grace_s=0.0)


class _SlowArray:
    """Stands in for a device array that is ready `seconds` after it is made."""

    def __init__(self, seconds: float):
        self.made, self.polls = time.perf_counter(), 0
        self._ready = threading.Event()
        timer = threading.Timer(seconds, self._ready.set)
        timer.daemon = True
        timer.start()

    def is_ready(self) -> bool:
        self.polls += 1
        return self._ready.is_set()

    def block_until_ready(self):
        self._ready.wait()
        return self


def test_the_wait_for_the_device_neither_polls_nor_holds_off_signal_handlers():
    """`run._wait` returns as the array becomes ready, having asked it once (no polling, which
    took processor time from the device's threads); a signal's handler runs during the wait
    (here SIGALRM's, which raises at once, long before the array is ready)."""
    import signal

    array = _SlowArray(0.3)
    run._wait(array, should_stop=lambda: False, grace_s=10.0)
    waited = time.perf_counter() - array.made
    assert 0.3 <= waited < 0.3 + 0.25 and array.polls == 1, (waited, array.polls)

    class Alarm(Exception):
        pass

    def handler(signum, frame):
        raise Alarm

    before = signal.signal(signal.SIGALRM, handler)
    try:
        array = _SlowArray(2.0)
        signal.setitimer(signal.ITIMER_REAL, 0.1)
        with pytest.raises(Alarm):
            run._wait(array, should_stop=None, grace_s=10.0)
        assert time.perf_counter() - array.made < 1.0
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, before)


def test_another_threads_import_waits_while_the_loop_follows_a_point(monkeypatch):
    """An import of a module not loaded yet, begun on another thread while the loop works
    between chunks (here, in `on_point`), waits until the loop waits for the device again
    (`background.LoopImportGate`); after the run Python's import is as it was. (A name no
    module has: the gate waits before Python looks for it, and the attempt ends only once
    the gate lets it go.)"""
    monkeypatch.setattr(background, "MAX_IMPORT_HOLD_S", 60.0)
    threads, held, missing = [], [], []

    def attempt():
        try:
            __import__(f"held_{uuid.uuid4().hex}")
        except ModuleNotFoundError:
            missing.append(True)

    def on_point(*_):
        if not threads:
            threads.append(threading.Thread(target=attempt, daemon=True))
            threads[0].start()
            threads[0].join(0.3)
            held.append(threads[0].is_alive())

    before = builtins.__import__
    assert run.run_training(CONFIG, seeds=2, on_point=on_point).status == run.FINISHED
    threads[0].join(10)
    assert held == [True] and missing == [True] and builtins.__import__ is before


def test_an_evaluation_and_its_confirmation_in_one_batch_return_what_each_alone_does():
    """The loop resets and steps an evaluation's and its confirmation's episodes as one batch:
    each episode starts where a batch of its own set starts it, and its return is the one it
    has there (to float32 rounding of a batch of another size: relative 1e-4)."""
    from sac_jax.evaluation import evaluate_from, initial_states
    from sac_jax.train import agent_for

    agent, env = agent_for(CONFIG)
    actor = agent.init(jax.random.key(0)).actor_params
    keys = jax.random.split(jax.random.key(1), 5)
    start, confirm_start = initial_states(env, keys[:2]), initial_states(env, keys[2:])
    both = initial_states(env, keys)
    np.testing.assert_allclose(both.obs, np.concatenate([start.obs, confirm_start.obs]),
                               rtol=1e-6)
    evaluate = jax.jit(lambda s: evaluate_from(agent, env, actor, s))
    np.testing.assert_allclose(
        evaluate(both), np.concatenate([evaluate(start), evaluate(confirm_start)]), rtol=1e-4)


def test_a_checkpoints_points_are_what_the_run_reported():
    """`evaluation_points` of a run's final state gives every point as `on_point` reported it,
    `stopped` included, which it derives from the delivered returns: here with seeds stopping
    at a return between those the run reaches, checked against the state's own flags after
    every point."""
    returns = run.run_training(CONFIG, seeds=2).metrics["delivered_return"]
    config = CONFIG.replace(stop_when_solved=True, stop_return=float(np.median(returns)))
    reported, flags = [], []
    result = run.run_training(
        config, seeds=2, on_point=lambda *point: reported.append(point[:3]),
        on_checkpoint=lambda runner, _: flags.append(float(np.mean(runner.stopped))))
    assert [means["stopped"] for _, means, _ in reported] == flags
    assert 0.0 < flags[-1] and flags[0] < 1.0, flags  # the check can tell counts apart
    rebuilt = run.evaluation_points(config, result.state)
    assert len(rebuilt) == len(reported) == result.points
    for (step, means, returns), (step2, means2, returns2) in zip(rebuilt, reported):
        assert step == step2 and means.keys() == means2.keys()
        np.testing.assert_array_equal(list(means.values()), list(means2.values()))
        np.testing.assert_array_equal(returns, returns2)


def test_the_collector_is_off_inside_the_tracing_block_and_left_as_it_was():
    """`run._collector_paused`: Python's cyclic collector is off inside, also when the block
    raises, and afterwards as it was before (on, or off where the caller had turned it off)."""
    assert gc.isenabled()
    with pytest.raises(ValueError):
        with run._collector_paused():
            assert not gc.isenabled()
            raise ValueError
    assert gc.isenabled()
    gc.disable()
    try:
        with run._collector_paused():
            assert not gc.isenabled()
        assert not gc.isenabled()
    finally:
        gc.enable()


@pytest.mark.parametrize("seed", [0, 7, 2**31 - 1, 2**31, 2**32 - 1])
def test_the_init_program_starts_each_run_from_the_seeds_split_key(seed):
    """`runs_init` splits the seed's key in the program as the host would have: run r of a
    sweep of 2 settings x 3 seeds starts from key r % 3 of split(key(seed), 3)."""
    start = jax.jit(run.runs_init(lambda key: jax.random.key_data(key), 3))
    runs, seed_value = run.start_args(seed, 6)
    expected = jax.random.key_data(jax.random.split(jax.random.key(seed), 3))
    np.testing.assert_array_equal(jax.vmap(start, (0, None))(runs, seed_value),
                                  np.concatenate([expected, expected]))
