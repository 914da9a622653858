"""sac_jax.memory: the need of a run from the shapes of its real state, and the refusal of a
run that cannot fit, through the command line (one line, exit 2, nothing written) and the
library (before anything is compiled)."""

import os

import jax
import pytest

import sac_jax
from sac_jax import memory, run
from sac_jax.run_dir import state_template
from scripts import train as train_script
from tests.saved_runs import fails_in_one_line

HUGE = ["--seeds", "64", "--buffer-size", "10000000", "--total-steps", "20000000"]
"""The issue's run: 64 seeds of 10^7 replay slots, 28 GB of replay data."""


@pytest.fixture
def machine_of_24_gb(monkeypatch):
    """The check sees 24 GB available on the CPU, whatever this machine has."""
    monkeypatch.setattr(memory, "available", lambda device=None: (24 * 10**9, "cpu"))


def test_the_replay_need_is_the_slots_data_and_the_rest_is_the_state():
    """InvertedPendulum-v5: a slot holds obs 4, action 1, reward 1, next obs 4, terminated 1
    float32 = 44 bytes; the state is every other byte of the eval_shape of the initial state.
    A checkpoint copies the whole state on an accelerator, on the CPU the state and the slots a
    run can fill (here 20,480 of 10^6 per seed)."""
    config = sac_jax.PRESETS["fast"].replace(buffer_size=1_000_000)
    need = memory.need(config, seeds=3, platform="gpu")
    assert need.replay == 3 * config.buffer_size * 44
    total = sum(x.size * x.dtype.itemsize for x in jax.tree_util.tree_leaves(
        state_template(config, 3)))
    assert need.replay + need.state == total
    assert need.peak == 2 * total and need.per_seed == need.peak // 3
    on_cpu = memory.need(config, seeds=3, platform="cpu")
    assert on_cpu.checkpoint == on_cpu.state + 3 * config.run_steps * 44


def test_a_run_that_cannot_fit_is_refused_in_one_line_and_writes_nothing(
        tmp_path, capsys, monkeypatch, machine_of_24_gb):
    out = str(tmp_path / "huge")
    fails_in_one_line(capsys, train_script.main, HUGE + ["--out", out], 2,
                      "need 56.5 GB (replay 28.2 GB + 75.0 MB state + 28.2 GB at a checkpoint), "
                      "24.0 GB available on cpu: lower --buffer-size or --seeds")
    assert not os.path.exists(out) and os.listdir(tmp_path) == []
    # an explicit override passes the check (stopped here before anything is compiled)
    monkeypatch.setattr(train_script, "run_training", lambda *a, **k: (_ for _ in ()).throw(
        SystemExit("reached the run")))
    with pytest.raises(SystemExit, match="reached the run"):
        train_script.main(HUGE + ["--out", out, "--no-memory-check"])


def test_the_library_entry_point_refuses_it_too(machine_of_24_gb):
    config = sac_jax.PRESETS["fast"].replace(buffer_size=10_000_000, total_steps=20_000_000)
    run.compiled_program.cache_clear()
    with pytest.raises(memory.MemoryRefused, match=r"^64 seed\(s\) of buffer_size=10000000 need"):
        run.run_training(config, seeds=64)
    assert run.compiled_program.cache_info().currsize == 0  # nothing was compiled


def test_the_header_shows_the_need_next_to_what_is_available(machine_of_24_gb):
    assert memory.check(sac_jax.PRESETS["fast"], 1) == (
        "replay 0.9 MB + 0.2 MB state + 1.1 MB at a checkpoint = 2.3 MB of 24.0 GB available "
        "on cpu")
