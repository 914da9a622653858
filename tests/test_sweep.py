"""scripts/sweep.py: the issue's command writes one CSV row per setting and seed, a plot and the
best setting as a train.py command line; settings that change no shape share one program and
the others get one each; a signal saves and `--resume` finishes the sweep exactly as an
uninterrupted one; bad input ends with one line, exit 2 and nothing written. That a swept
setting trains exactly as a run of its own config does is checked in float64 by
tests/test_train.py (`test_a_sweep_equals_separate_runs_of_its_settings`)."""

import contextlib
import csv
import io
import math
import os
import shutil

import pytest

import sac_jax
from sac_jax import run_checkpoint
from scripts import sweep as sweep_script
from scripts import train as train_script
from tests.signals import interrupted_main

# The issue's command line.
SWEEP = ["--preset", "pendulum", "--total-steps", "3000", "--eval-every", "1000", "--seeds",
         "2", "--set", "actor_lr=1e-3,3e-4"]


def _rows(out):
    with open(os.path.join(out, "results.csv")) as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory):
    """The issue's sweep, whole; and the same sweep stopped by SIGINT, then resumed."""
    root = tmp_path_factory.mktemp("sweeps")
    whole, stopped = str(root / "whole"), str(root / "stopped")
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert sweep_script.main(SWEEP + ["--out", whole]) == 0
    code = interrupted_main(sweep_script, SWEEP + ["--out", stopped])
    interrupted = str(root / "interrupted")
    shutil.copytree(stopped, interrupted)
    resumed = sweep_script.main(["--resume", stopped])
    return {"whole": whole, "stopped": stopped, "interrupted": interrupted, "code": code,
            "resumed": resumed, "printed": printed.getvalue()}


def test_the_issues_sweep_writes_one_row_per_setting_and_seed(sweeps, capsys):
    rows = _rows(sweeps["whole"])
    assert [(r["setting"], r["actor_lr"], r["seed"]) for r in rows] == [
        ("0", "0.001", "0"), ("0", "0.001", "1"), ("1", "0.0003", "0"), ("1", "0.0003", "1")]
    assert {"delivered_return", "solved_at_step", "eval_return", "critic_loss", "actor_loss",
            "alpha", "env_steps"} <= set(rows[0])
    assert all(r["env_steps"] == "3000" for r in rows)
    # the two settings train differently on the same two keys; the seeds differ too
    returns = [float(r["delivered_return"]) for r in rows]
    assert len(set(returns)) == 4
    assert {"sweep.json", "results.csv", "sweep.png", "programs"} <= set(
        os.listdir(sweeps["whole"]))
    assert os.listdir(os.path.join(sweeps["whole"], "programs")) == ["0"]


def test_a_swept_run_loads_as_a_policy(sweeps):
    """Run 3 of the program = setting 1, seed 1 (setting-major)."""
    path = os.path.join(sweeps["whole"], "programs", "0")
    policy = sac_jax.load_policy(path, seed=3)
    assert policy([0.0, 1.0, 0.0]).shape == (1,)
    assert policy.config.actor_lr == 3e-4 and sac_jax.load_policy(path, 1).config.actor_lr == 1e-3
    with pytest.raises(ValueError, match="has seeds 0..3"):
        sac_jax.load_policy(path, seed=4)


def test_the_best_setting_is_printed_as_a_train_command(sweeps):
    rows = _rows(sweeps["whole"])
    means = {s: sum(float(r["delivered_return"]) for r in rows if r["setting"] == s) / 2
             for s in ("0", "1")}
    best = max(means, key=means.get)
    lr = {"0": 1e-3, "1": 3e-4}[best]
    assert sweep_script.best_setting(
        [dict(r, setting=int(r["setting"]), delivered_return=float(r["delivered_return"]),
              solved_at_step=None) for r in rows], 2)[0] == int(best)
    config = sac_jax.PRESETS["pendulum"].replace(total_steps=3000, eval_every=1000,
                                                 actor_lr=lr)
    command = sweep_script.train_command("pendulum", config)
    default = lr == sac_jax.PRESETS["pendulum"].actor_lr  # a flag only where it differs
    assert command == ("python scripts/train.py --preset pendulum --total-steps 3000 "
                       "--eval-every 1000" + ("" if default else f" --actor-lr {lr!r}"))
    assert train_script.parse_args(command.split()[2:]).config == config
    last = sweeps["printed"].strip().splitlines()[-1]
    assert last.startswith(f"best setting {best} (") and last.endswith(
        f": mean delivered return {means[best]:.1f} over 2 seed(s); train it with: "
        f"{command}; wrote {sweeps['whole']}"), last


def test_the_best_setting_breaks_a_tie_by_the_earliest_mean_solved_step():
    """Equal mean returns: the setting whose seeds were solved sooner on average wins, one never
    solved counting as the latest; a seed that delivered no actor (a NaN or -inf return) puts
    its setting below every setting whose seeds all delivered, however high its others."""
    row = lambda setting, ret, step: dict(setting=setting, delivered_return=ret,
                                          solved_at_step=step)
    rows = [row(0, 900.0, 5000), row(0, 1000.0, None), row(1, 950.0, 7000),
            row(1, 950.0, 9000), row(2, 950.0, 9000), row(2, float("nan"), 9000),
            row(3, 2000.0, 1000), row(3, -math.inf, None)]
    assert sweep_script.best_setting(rows, 4) == (1, 950.0)  # 0 and 1 at 950; 8000 before inf
    rows[5] = row(2, 950.0, 6000)
    assert sweep_script.best_setting(rows, 4) == (2, 950.0)  # 7500 before 8000


def test_train_command_round_trips_every_kind_of_flag():
    config = sac_jax.PRESETS["fast"].replace(actor_hidden=(32, 16), stop_when_solved=False,
                                             stop_return=None, init="torch", batch_size=128)
    command = sweep_script.train_command("fast", config)
    assert train_script.parse_args(command.split()[2:]).config == config


def test_a_stopped_sweep_resumes_to_the_uninterrupted_result(sweeps):
    assert sweeps["code"] == 130 and sweeps["resumed"] == 0
    assert run_checkpoint.saved_steps(os.path.join(sweeps["interrupted"], "programs", "0"))
    assert not os.path.exists(os.path.join(sweeps["interrupted"], "results.csv"))
    timing = ("solved_wall_s",)
    strip = lambda rows: [{k: v for k, v in r.items() if k not in timing} for r in rows]
    assert strip(_rows(sweeps["stopped"])) == strip(_rows(sweeps["whole"]))


def test_settings_that_change_a_shape_get_a_program_each():
    base = sac_jax.PRESETS["fast"]
    grid = sweep_script.parse_sets(["batch_size=128,256", "actor_lr=1e-3,3e-3", "tau=0.01"])
    points, programs = sweep_script.plan(base, grid)
    assert len(points) == 4 and points[1] == {"batch_size": 128, "actor_lr": 3e-3, "tau": 0.01}
    assert [p.indices for p in programs] == [(0, 1), (2, 3)]
    assert [p.config.batch_size for p in programs] == [128, 256]
    assert programs[0].settings == {"actor_lr": [1e-3, 3e-3], "tau": [0.01, 0.01]}
    # one setting per program: its values are the program's constants
    _, programs = sweep_script.plan(base, sweep_script.parse_sets(["batch_size=128,256",
                                                                  "tau=0.01"]))
    assert [(p.settings, p.config.tau, p.config.batch_size) for p in programs] == [
        (None, 0.01, 128), (None, 0.01, 256)]


@pytest.mark.parametrize("argv, message", [
    (["--set", "no_such_field=1,2"], "error: --set no_such_field: SACConfig has no such field"),
    (["--set", "variant=1,2"], "error: --set variant: not a numeric hyperparameter"),
    (["--set", "actor_lr="], "error: --set actor_lr: no values"),
    (["--set", "actor_lr=1e-3,fast"], "error: --set actor_lr='fast': not a number"),
    (["--set", "batch_size=1.5"], "error: --set batch_size='1.5': not an integer"),
    (["--set", "actor_lr=1e-3,-1"], "error: --set setting actor_lr=-1: SACConfig.actor_lr=-1.0: "
                                    "must be > 0"),
    (["--set", "tau=0.1", "--set", "tau=0.2"], "error: --set tau: given twice"),
    (["--set", "batch_size=64,128,64"], "error: --set batch_size: 64 given more than once"),
    (["--set", "actor_lr"], "error: --set 'actor_lr': expected FIELD=V1,V2,..."),
    ([], "error: --set: give at least one FIELD=V1,V2,... to sweep"),
    (["--resume", "x", "--set", "tau=0.1"], "error: --resume=x: a resumed sweep keeps its own "
                                            "configuration; remove --set"),
])
def test_bad_input_ends_with_one_line_exit_2_and_nothing_written(argv, message, tmp_path,
                                                                  capsys):
    out = tmp_path / "sweep"
    assert sweep_script.main(argv + ["--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(message) and "\n" not in err and "Traceback" not in err, err
    assert not out.exists() and os.listdir(tmp_path) == []
