"""scripts/train.py: bad input ends with one line naming the problem and exit code 2, before
anything is compiled or written; the progress line."""

import importlib.util
import math
import os

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
spec = importlib.util.spec_from_file_location("train_script", os.path.join(ROOT, "scripts", "train.py"))
train_script = importlib.util.module_from_spec(spec)
spec.loader.exec_module(train_script)


@pytest.mark.parametrize("argv, message", [
    (["--tau", "3"], "error: SACConfig.tau=3.0: must lie in (0, 1]"),
    (["--env", "Nope-v0"], "error: SACConfig.env='Nope-v0': unknown environment"),
    (["--batch-size", "0"], "error: SACConfig.batch_size=0: must be a positive integer"),
    (["--seeds", "0"], "error: --seeds=0: must be at least 1"),
])
def test_bad_values_end_with_one_line_and_exit_code_2(argv, message, capsys):
    assert train_script.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(message) and "\n" not in err and "Traceback" not in err


def test_an_existing_run_directory_is_not_touched(tmp_path, capsys):
    (tmp_path / "keep.txt").write_text("mine")
    assert train_script.main(["--out", str(tmp_path)]) == 2
    assert "already exists" in capsys.readouterr().err
    assert os.listdir(tmp_path) == ["keep.txt"]


def test_unknown_preset_and_malformed_values_are_rejected_by_the_parser(capsys):
    for argv in (["--preset", "nope"], ["--learn-alpha", "maybe"], ["--num-envs", "two"]):
        with pytest.raises(SystemExit) as exit_info:
            train_script.main(argv)
        assert exit_info.value.code == 2


def test_every_config_field_is_a_documented_flag():
    help_text = train_script.build_parser().format_help()
    for flag in ("--num-envs", "--updates-per-step", "--log-prob-correction", "--update-order"):
        assert flag in help_text
    assert "Polyak coefficient" in help_text


def test_progress_line_shows_undefined_values_as_a_dash():
    point = {"eval_return": 1000.0, "train_return": math.nan, "alpha": 0.0161,
             "critic_loss": 2.73, "actor_loss": -41.6}
    line = train_script._progress_line(20480, point, 1, 26.0)
    assert "eval    1000.0" in line and "train         -" in line and "alpha 0.016" in line
