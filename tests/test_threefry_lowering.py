"""`sac_jax.threefry_lowering`: the same bits with and without Threefry's loop, the loop gone
only within `unrolled()`, and the training program lowered so by `sac_jax.run`."""

import contextlib
import re

import jax
import numpy as np

from sac_jax import threefry_lowering


def draws(key):
    """One of each draw a training iteration makes, from a chain of splits."""
    key, k_normal, k_uniform, k_slots = jax.random.split(key, 4)
    return (jax.random.normal(k_normal, (256, 3)),
            jax.random.uniform(k_uniform, (8, 1), minval=-3.0, maxval=3.0),
            jax.random.randint(k_slots, (4, 256), 0, 10_000), jax.random.key_data(key))


def lowered(unrolled: bool):
    """`draws` lowered anew (JAX keeps a function's lowering for its shapes: a new one each
    time), within `unrolled()` or not."""
    with threefry_lowering.unrolled() if unrolled else contextlib.nullcontext():
        return jax.jit(lambda key: draws(key)).lower(jax.random.key(7))


def test_the_unrolled_lowering_draws_the_same_bits_without_a_loop_and_only_within_its_block():
    looped, unrolled = lowered(False), lowered(True)
    assert "stablehlo.while" in looped.as_text()
    assert "stablehlo.while" not in unrolled.as_text()
    for a, b in zip(looped.compile()(jax.random.key(7)), unrolled.compile()(jax.random.key(7))):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert "stablehlo.while" in lowered(False).as_text()  # the block ended: JAX's own again


def test_the_choice_is_per_thread_and_restored_after_an_error():
    import threading

    seen = {}
    with threefry_lowering.unrolled():
        thread = threading.Thread(
            target=lambda: seen.update(text=lowered(False).as_text()))
        thread.start()
        thread.join()
    assert "stablehlo.while" in seen["text"]
    try:
        with threefry_lowering.unrolled():
            raise KeyError("inside")
    except KeyError:
        pass
    assert "stablehlo.while" in lowered(False).as_text()


def test_the_run_lowers_its_training_program_unrolled_and_its_evaluation_as_jax_does(monkeypatch):
    """In the compiled programs, a Threefry loop is a `while` of 5 trips whose state ends in
    the two rotation tables, (..., u32[4], u32[4])."""
    from sac_jax import run
    from sac_jax.presets import PRESETS

    config = PRESETS["fast"].replace(env="Pendulum-v1", num_envs=1, updates_per_step=1,
                                     total_steps=600, learning_starts=256, buffer_size=600,
                                     eval_every=100, stop_when_solved=False)
    monkeypatch.setattr(run, "program_directory", lambda: None)  # lowered here, not loaded
    _, _, chunk, _ = run._compiled_program.__wrapped__(config, 1, ())
    loops = lambda program: len(re.findall(r"u32\[4\]\{0\}, u32\[4\]\{0\}\) while\(",
                                           program.as_text()))
    assert loops(chunk.advance) == 0
    assert loops(chunk.evaluate) > 0
