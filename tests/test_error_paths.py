"""One-line errors that no other test reaches: each bad value is named in a single line (a
ValueError, or a script's exit 2), before anything is trained or written."""

from __future__ import annotations

import os

import pytest

from sac_jax import SACConfig, hyperparams, run_checkpoint
from scripts import sweep as sweep_script
from scripts import train as train_script
from tests.saved_runs import fails_in_one_line, two_checkpoints


def test_a_resume_step_without_resume_is_refused(capsys):
    fails_in_one_line(capsys, train_script.main, ["--resume-step", "5"], 2,
                      "--resume-step=5: only with --resume")


@pytest.mark.parametrize("fields, message", [
    ({"learning_starts": 1.5}, "SACConfig.learning_starts=1.5: must be an integer"),
    ({"env": "playground/AcrobotSwingup", "stop_when_solved": True},
     "SACConfig.stop_when_solved=True: playground/AcrobotSwingup has no solved return to stop "
     "at; set stop_return"),
])
def test_a_config_field_that_cannot_hold_is_named(fields, message):
    with pytest.raises(ValueError) as raised:
        SACConfig(**fields)
    assert str(raised.value) == message


@pytest.mark.parametrize("settings, message", [
    ({"num_envs": [4, 8]}, "settings: num_envs is not a hyperparameter one program can vary"),
    ({"actor_lr": [1e-3, 3e-4], "tau": [0.01]},
     "settings: every hyperparameter needs the same number (>= 1) of values"),
])
def test_a_sweep_setting_that_one_program_cannot_run_is_named(settings, message):
    with pytest.raises(ValueError) as raised:
        hyperparams.sweep(SACConfig(), settings, seeds=1)
    assert str(raised.value).startswith(message), raised.value


def test_a_checkpoint_step_that_is_not_there_names_the_steps_that_are(tmp_path):
    path, _ = two_checkpoints(str(tmp_path / "run"))
    with pytest.raises(run_checkpoint.checkpoint.CheckpointError,
                       match=r"999: no such step \(steps: \[0, 800\]\)$"):
        run_checkpoint.load_checkpoint(path, step=999)


def test_resuming_a_directory_that_is_no_sweep_and_a_sweep_into_one_that_exists(tmp_path,
                                                                                capsys):
    other = tmp_path / "other"
    other.mkdir()
    fails_in_one_line(capsys, sweep_script.main, ["--resume", str(other)], 2,
                      f"--resume={other}: not a readable sweep directory")
    fails_in_one_line(capsys, sweep_script.main, ["--out", str(other), "--set",
                                                  "actor_lr=1e-3,3e-4"], 2,
                      f"--out={other}: already exists; choose a new directory")
    assert os.listdir(other) == []
