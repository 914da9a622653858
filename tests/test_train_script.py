"""scripts/train.py: bad input ends with one line naming the problem and exit code 2, before
anything is compiled or written; the run directory; a signal saves a checkpoint and `--resume`
ends exactly where an uninterrupted run does; a non-finite state stops the run, saving the
delivered actors its summary describes; the progress line."""

import csv
import dataclasses
import json
import math
import os
import shutil
import subprocess
import sys
import time

import numpy as np
import pytest

import jax

import envs
import sac_jax
from sac_jax import run_checkpoint, run_dir, tracking, wandb_records
from sac_jax.cli import progress_line
from scripts import train as train_script
from tests.killed_run import tensorboard_steps, wandb_steps
from tests.saved_runs import SMALL_RUN as RUN
from tests.signals import interrupted_main
from tests.subprocess_json import ROOT, run_json


@pytest.mark.parametrize("argv, message", [
    (["--tau", "3"], "error: SACConfig.tau=3.0: must lie in (0, 1]"),
    (["--env", "Nope-v0"], "error: SACConfig.env='Nope-v0': unknown environment"),
    (["--batch-size", "0"], "error: SACConfig.batch_size=0: must be a positive integer"),
    (["--seeds", "0"], "error: --seeds=0: must be a positive integer"),
    (["--seed", "-1"], "error: --seed=-1: must be an integer in [0, 2**32)"),
    (["--seed", str(2 ** 32)], f"error: --seed={2 ** 32}: must be an integer in [0, 2**32)"),
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


@pytest.mark.parametrize("argv, message", [
    (["--preset", "nope"], f"error: --preset='nope': must be one of {list(sac_jax.PRESETS)}"),
    (["--variant", "v3"], "error: --variant='v3': must be one of ['v2', 'v1']"),
    (["--num-envs", "two"], "error: --num-envs: invalid literal for int() with base 10: 'two'"),
    (["--tau"], "error: --tau: expected a value"),
    (["--taux", "1"], "error: unrecognized arguments: --taux 1"),
    (["--resume", "runs/x", "--tau", "0.1"], "error: --resume=runs/x: a resumed run keeps its "
                                             "own configuration; remove --tau"),
])
def test_unknown_preset_and_malformed_values_end_with_one_line(argv, message, capsys):
    assert train_script.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(message) and "\n" not in err, err


def test_resume_errors_name_the_problem_and_touch_nothing(tmp_path, capsys):
    assert train_script.main(["--resume", str(tmp_path / "missing")]) == 2
    assert "no such run directory" in capsys.readouterr().err
    (tmp_path / "junk.txt").write_text("mine")
    assert train_script.main(["--resume", str(tmp_path)]) == 2
    assert "not a readable run directory" in capsys.readouterr().err
    assert os.listdir(tmp_path) == ["junk.txt"]


def test_every_config_field_is_a_documented_flag_with_the_presets_defaults(capsys):
    with pytest.raises(SystemExit) as exit_info:
        train_script.main(["--preset", "cleanrl", "--help"])
    assert exit_info.value.code == 0
    help_text = " ".join(capsys.readouterr().out.split())
    for field in dataclasses.fields(sac_jax.SACConfig):
        flag = "--" + field.name.replace("_", "-")
        assert (flag in help_text) == (field.name != "data_parallel_axis"), flag
    assert "Polyak coefficient" in help_text and "(default: InvertedPendulum-v4)" in help_text


def test_flags_override_the_chosen_preset():
    args = train_script.parse_args(["--preset", "pendulum", "--tau", "0.01", "--actor-hidden",
                                    "32", "32", "--no-learn-alpha", "--alpha-init", "0.2"])
    assert args.config == sac_jax.PRESETS["pendulum"].replace(
        tau=0.01, actor_hidden=(32, 32), learn_alpha=False, alpha_init=0.2)


def test_progress_line_shows_undefined_values_as_a_dash():
    point = {"eval_return": 1000.0, "train_return": math.nan, "alpha": 0.0161,
             "critic_loss": 2.73, "actor_loss": -41.6}
    line = progress_line(20480, point, 1, 26.0)
    assert "eval    1000.0" in line and "train         -" in line and "alpha 0.016" in line


def test_progress_line_counts_the_seeds_solved_and_stopped():
    point = {"eval_return": 980.0, "delivered_return": 990.0, "train_return": 900.0,
             "alpha": 0.02, "critic_loss": 2.0, "actor_loss": -40.0, "solved": 0.75,
             "stopped": 0.0}
    line = progress_line(7168, point, 256, 4.3)
    assert line.endswith(" s | solved 192/256") and "delivered     990.0" in line
    point.update(stopped=0.5)
    assert progress_line(7168, point, 256, 4.3).endswith(
        " s | solved 192/256, stopped 128")
    assert progress_line(7168, dict(point, solved=1.0, stopped=1.0), 1,
                                       1.7).endswith(" s | solved 1/1, stopped 1")
    del point["solved"]  # a task without a solved return
    assert "solved" not in progress_line(7168, point, 1, 1.7)


def test_progress_line_tells_the_time_left_at_the_speed_so_far():
    point = {"eval_return": 50.0}
    # a quarter of 4,096,000 steps in 30 s: three quarters, 90 s, to go
    assert progress_line(1_024_000, point, 1, 30.0, 4_096_000).endswith(
        " 30.0 s, 90 s left")
    assert progress_line(8192, point, 16, 30.0, 4_096_000).endswith(" 4.2 h left")
    assert progress_line(409_600, point, 1, 40.0, 4_096_000).endswith(" 6 min left")
    assert "left" not in progress_line(4_096_000, point, 1, 120.0, 4_096_000)
    assert "left" not in progress_line(8192, point, 1, 30.0)
    solved = progress_line(7168, dict(point, solved=0.0), 1, 2.0, 20480)
    assert solved.endswith(" 2.0 s, 4 s left | solved 0/1")
    ended = progress_line(7168, dict(point, solved=1.0, stopped=1.0), 1, 2.0, 20480)
    assert ended.endswith(" 2.0 s | solved 1/1, stopped 1")  # the run ends here


def test_the_summary_line_never_prints_none():
    summary = {"delivered_return": [66.5, 1000.0], "solved_at_step": [None, 7168],
               "solved_threshold": 950.0}
    assert train_script._outcome(summary).endswith("; solved (>= 950) at step [-, 7168]")
    summary.update(solved_at_step=[None, None])
    assert train_script._outcome(summary).endswith("; not solved (>= 950)")
    assert "None" not in train_script._outcome(summary)


# ---------------------------------------------------------------- runs (Pendulum-v1, tiny)
TIMING = ("wall_s", "steps_per_s")


def _metrics(path):
    """metrics.csv without the timing columns."""
    with open(os.path.join(path, "metrics.csv")) as f:
        return [{k: v for k, v in row.items() if k not in TIMING} for row in csv.DictReader(f)]


def _checkpoint_arrays(path, step=None):
    """The leaves of the checkpoint's state at `step` (default the newest), PRNG keys as their
    key data."""
    _, _, state, _ = run_checkpoint.load_checkpoint(path, step)
    return [np.asarray(jax.random.key_data(x)) if jax.dtypes.issubdtype(
        x.dtype, jax.dtypes.prng_key) else np.asarray(x) for x in jax.tree_util.tree_leaves(state)]


def _interrupted_run(out: str, signals: int) -> int:
    """`main(RUN --out out)` sent `signals` real SIGINTs at its first evaluation point."""
    return interrupted_main(train_script, RUN + ["--out", out], signals)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """An uninterrupted run, and the same run stopped by SIGINT at its first evaluation point."""
    root = tmp_path_factory.mktemp("runs")
    whole, stopped = str(root / "whole"), str(root / "stopped")
    assert train_script.main(RUN + ["--out", whole]) == 0
    code = _interrupted_run(stopped, signals=1)
    interrupted = str(root / "interrupted")
    shutil.copytree(stopped, interrupted)
    return {"whole": whole, "stopped": stopped, "interrupted": interrupted, "code": code,
            "root": root}


def test_a_finished_run_directory_holds_every_output(runs):
    files = set(os.listdir(runs["whole"]))
    assert {"config.json", "run.json", "checkpoints", "metrics.csv", "summary.json",
            "curves.png", "tensorboard"} <= files
    assert not [f for f in files if "tmp" in f]
    summary = json.load(open(os.path.join(runs["whole"], "summary.json")))
    assert summary["status"] == "finished" and summary["preset"] == "pendulum"
    assert summary["total_steps"] == 4000 and len(summary["eval_return"]) == 1
    assert {"env", "seeds", "solved_at_step", "solved_wall_s", "solved_process_s",
            "delivered_return", "delivered_at_step", "delivered_wall_s", "stopped", "wall_s",
            "compile_s"} <= set(summary)
    rows = _metrics(runs["whole"])
    # the delivered actor: its kept score after the last point, selected at one of the points
    assert summary["delivered_return"] == [float(rows[-1]["delivered_return"])]
    assert summary["delivered_at_step"][0] in [int(r["env_steps"]) for r in rows]
    rows = _metrics(runs["whole"])
    assert [int(r["env_steps"]) for r in rows] == [2000, 3000, 4000]
    assert open(os.path.join(runs["whole"], "curves.png"), "rb").read(8) == b"\x89PNG\r\n\x1a\n"


def test_training_switches_threads_more_often_and_writes_its_records_in_another_process(
        tmp_path, monkeypatch):
    """The thread switch interval is `TRAINING_SWITCH_INTERVAL_S` while the run trains and as
    before after it; TensorBoard's records and curves.png come from a
    `records_process.RecordsProcess` started as training began (writing either in this process
    fails here)."""
    from sac_jax import cli, plots, records_process

    seen, line = [], cli.progress_line
    monkeypatch.setattr(cli, "progress_line",
                        lambda *args: seen.append(sys.getswitchinterval()) or line(*args))
    monkeypatch.setattr(plots, "write_curves", lambda *args: 1 / 0)
    monkeypatch.setattr(records_process, "TensorBoard", lambda *args: 1 / 0)
    before = sys.getswitchinterval()
    assert train_script.main(RUN + ["--out", str(tmp_path / "run")]) == 0
    assert len(seen) == 3 and seen == pytest.approx([cli.TRAINING_SWITCH_INTERVAL_S] * 3)
    assert sys.getswitchinterval() == before != pytest.approx(cli.TRAINING_SWITCH_INTERVAL_S)
    assert open(tmp_path / "run" / "curves.png", "rb").read(8) == b"\x89PNG\r\n\x1a\n"
    steps = [step for step, _ in _scalars(tmp_path / "run" / "tensorboard", "mean/eval_return")]
    assert steps == [2000, 3000, 4000]


def tensorboard_scalars(event_dir):
    """[(tag, step, value)] of every scalar in the TensorBoard event files of `event_dir`, in
    file-name (creation) order and then as written, duplicates kept: read with TensorBoard's
    own loader, as stored (its accumulator would purge re-written steps)."""
    from tensorboard.backend.event_processing.event_file_loader import LegacyEventFileLoader

    found = []
    for name in sorted(os.listdir(event_dir)):
        for event in LegacyEventFileLoader(os.path.join(event_dir, name)).Load():
            found += [(v.tag, event.step, v.simple_value) for v in event.summary.value]
    return found


def _scalars(event_dir, tag):
    """(step, value) of `tag` in the TensorBoard event files of `event_dir`."""
    return [(step, value) for name, step, value in tensorboard_scalars(event_dir) if name == tag]


def test_tensorboard_events_hold_every_evaluation_point(runs, tmp_path, monkeypatch):
    points = _scalars(os.path.join(runs["whole"], "tensorboard"), "mean/eval_return")
    csv_returns = [float(r["eval_return"]) for r in _metrics(runs["whole"])]
    assert [step for step, _ in points] == [2000, 3000, 4000]
    # TensorBoard stores float32, the CSV decimal text: one float32 rounding apart (2^-24 < 1e-6)
    np.testing.assert_allclose([value for _, value in points], csv_returns, rtol=1e-6)
    # one seed: solved is 1 where its delivered actor's score is at the threshold, here one
    # between the run's scores (Pendulum-v1's -250 is above them all), so both values occur
    delivered = [float(r["delivered_return"]) for r in _metrics(runs["whole"])]
    spec = envs.spec("Pendulum-v1")
    monkeypatch.setitem(envs.registry.SPECS, spec.name, dataclasses.replace(
        spec, solved_return=(min(delivered) + max(delivered)) / 2))  # read by the host alone
    again = str(tmp_path / "again")
    assert train_script.main(RUN + ["--out", again]) == 0
    solved = [value for _, value in _scalars(os.path.join(again, "tensorboard"), "mean/solved")]
    delivered = np.array([float(r["delivered_return"]) for r in _metrics(again)])
    expected = (delivered >= envs.spec("Pendulum-v1").solved_return).astype(float)
    assert 0.0 in expected and 1.0 in expected, delivered
    assert solved == list(expected)


def _killed(argv, step: int) -> subprocess.CompletedProcess:
    """scripts/train.py `argv` in a process of its own, SIGKILLed at the checkpoint of the
    evaluation point at `step` once TensorBoard holds that point (tests/killed_run.py)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        filter(None, [ROOT, os.environ.get("PYTHONPATH")])))
    return subprocess.run([sys.executable, "-m", "tests.killed_run", str(step), *argv],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)


def _last_checkpointed_step(out) -> int:
    return max(map(int, run_checkpoint.load_checkpoint(out)[3].walls))


@pytest.fixture
def offline_wandb(tmp_path, monkeypatch):
    """W&B offline (never the network), quiet, its files under tmp_path/wandb-dir."""
    monkeypatch.setenv("WANDB_MODE", "offline")
    monkeypatch.setenv("WANDB_SILENT", "true")
    monkeypatch.setenv("WANDB_DIR", str(tmp_path / "wandb-dir"))
    os.makedirs(tmp_path / "wandb-dir")
    return str(tmp_path / "wandb-dir")


def test_threads_never_build_syntax_trees_at_once(tmp_path, offline_wandb):
    """W&B's start and matplotlib's import, on three threads at once, parse Python source (wandb's
    pydantic models, matplotlib's rc values), which CPython 3.11 cannot do on two threads at once
    (SystemError "AST constructor recursion depth mismatch"): W&B's thread and the one that
    imported matplotlib parse, each call holding `background.SYNTAX_TREE_IMPORTS`, and none
    begins while another thread is inside one."""
    pytest.importorskip("wandb")
    seen = run_json(["-m", "tests.concurrent_imports", str(tmp_path)])
    threads = set(seen["calls"])
    assert any(name.startswith("ThreadPoolExecutor") for name in threads), seen  # W&B's
    assert threads & {"MainThread", "plots.prepare"}, seen  # whichever imported matplotlib
    assert sum(seen["unguarded"].values()) == 0, seen
    assert sum(seen["overlapping"].values()) == 0, seen


def test_each_point_is_logged_once_after_kills_and_resumes(runs, tmp_path, offline_wandb):
    """A run tracked on W&B (offline), SIGKILLed twice, each time after TensorBoard wrote a
    point whose checkpoint was not saved yet (so the resumed run computes it again),
    then resumed to the end: every (tag, step) is in TensorBoard's event files exactly once
    with the uninterrupted run's value, and W&B's logs (one per process) hold each step once,
    with the same scalars, and the summary."""
    pytest.importorskip("wandb")
    out = str(tmp_path / "killed")
    for argv, step in ((RUN + ["--out", out, "--track"], 3000), (["--resume", out], 4000)):
        killed = _killed(argv, step)
        assert killed.returncode == -9, killed.stderr[-3000:]
        assert step in tensorboard_steps(os.path.join(out, "tensorboard"))
        print("W&B held after the kill:", sorted(wandb_steps(out)))
        assert _last_checkpointed_step(out) == step - 1000  # the point will be computed again
        time.sleep(1.0)  # W&B names a process's log folder by the second: the next has its own
    assert train_script.main(["--resume", out]) == 0
    scalars = tensorboard_scalars(os.path.join(out, "tensorboard"))
    keys = [(tag, step) for tag, step, _ in scalars]
    assert len(keys) == len(set(keys)), sorted(k for k in keys if keys.count(k) > 1)
    whole = tensorboard_scalars(os.path.join(runs["whole"], "tensorboard"))
    assert {tag for tag, _, _ in whole} >= {"mean/eval_return", "mean/stopped",
                                            "eval_return/seed_0"}
    assert sorted(scalars) == sorted(whole)  # bit for bit: a resumed run is the same run
    assert [(s, v) for tag, s, v in sorted(scalars) if tag == "eval_return/seed_0"] == [
        (int(r["env_steps"]), np.float32(r["eval_return"])) for r in _metrics(out)]
    run_id = tracking.load_settings(out)["id"]
    logs = wandb_records.logs(offline_wandb, run_id)
    assert len(logs) == 3  # the two killed processes and the last
    rows = [row for path in logs for row in wandb_records.history(path)]
    assert [row["_step"] for row in rows] == [2000, 3000, 4000]
    for row in rows:
        logged = {(tag, row["_step"], np.float32(v)) for tag, v in row.items()
                  if not tag.startswith("_")}
        assert logged == {s for s in scalars if s[1] == row["_step"]}
    summary = json.load(open(os.path.join(out, "summary.json")))
    final = wandb_records.summary(logs[-1])
    assert final["status"] == "finished" and final["total_steps"] == 4000
    assert final["delivered_return"] == summary["delivered_return"]


def test_sigint_saves_a_checkpoint_and_summary_then_exits_130(runs):
    assert runs["code"] == 130
    summary = json.load(open(os.path.join(runs["interrupted"], "summary.json")))
    assert summary["status"] == "interrupted" and summary["total_steps"] == 2000
    assert run_checkpoint.saved_steps(runs["interrupted"]) == [2000]


def test_a_resumed_run_ends_exactly_like_the_uninterrupted_one(runs, capsys):
    assert train_script.main(["--resume", runs["stopped"]]) == 0
    # the wait for the programs has a line of its own, with its seconds (which the summary's
    # compile_s adds to the interrupted run's)
    compiled = capsys.readouterr().out.splitlines()[1]
    assert compiled.startswith("compiling the programs (") and compiled.endswith(" s"), compiled
    summary = json.load(open(os.path.join(runs["stopped"], "summary.json")))
    # both runs' compiles, against this run's printed to 0.1 s
    assert summary["compile_s"] >= float(compiled.split()[-2]) - 0.05
    assert _metrics(runs["stopped"]) == _metrics(runs["whole"])
    resumed, whole = _checkpoint_arrays(runs["stopped"]), _checkpoint_arrays(runs["whole"])
    assert len(resumed) == len(whole)
    for a, b in zip(resumed, whole):  # parameters, optimiser states, buffers, keys: bit for bit
        np.testing.assert_array_equal(a, b)
    assert train_script.main(["--resume", runs["whole"]]) == 2  # finished: nothing to do


def test_a_run_killed_after_its_last_checkpoint_gets_its_result_files_on_resume(runs, tmp_path):
    killed = str(tmp_path / "killed")
    shutil.copytree(runs["whole"], killed)
    for name in ("summary.json", "metrics.csv", "curves.png"):
        os.remove(os.path.join(killed, name))
    assert train_script.main(["--resume", killed]) == 0
    assert _metrics(killed) == _metrics(runs["whole"])
    assert json.load(open(os.path.join(killed, "summary.json")))["status"] == "finished"
    assert os.path.exists(os.path.join(killed, "curves.png"))


def test_a_non_finite_state_stops_the_run_and_saves_what_its_summary_describes(runs, capsys):
    """A state gone non-finite ends the run after the chunk's point: the state is saved with
    the delivered actors that summary.json describes (finite: finite evaluations selected
    them), the good checkpoint before it is kept unchanged, and a resume of the non-finite
    state, which would stop again at once, is refused in one line."""
    diverging = str(runs["root"] / "diverging")
    shutil.copytree(runs["interrupted"], diverging)
    config_path = os.path.join(diverging, "config.json")
    config = json.load(open(config_path))
    json.dump(dict(config, reward_scale=1e30), open(config_path, "w"))  # Q targets overflow
    good = _checkpoint_arrays(diverging)
    assert train_script.main(["--resume", diverging]) == 1
    err = capsys.readouterr().err.strip()
    # the critic's targets overflow first; the actor, which reads the critic, follows in the
    # same update and comes first in the state's order: the first to go non-finite is named
    assert err.startswith("error: non-finite critic_") and "of seed 0 between environment steps 2000 and 3000" in err
    assert ("its delivered policy is saved with the state at step 3000; resuming would repeat "
            "the same updates: train anew with other settings") in err and "\n" not in err
    assert run_checkpoint.saved_steps(diverging) == [2000, 3000]
    for a, b in zip(_checkpoint_arrays(diverging, 2000), good, strict=True):
        np.testing.assert_array_equal(a, b)
    summary = json.load(open(os.path.join(diverging, "summary.json")))
    assert summary["status"] == "non-finite" and summary["total_steps"] == 3000
    _, _, state, _ = run_checkpoint.load_checkpoint(diverging)
    assert summary["delivered_at_step"] == [int(s) for s in np.ravel(state.delivered.env_steps)]
    assert all(np.isfinite(x).all() for x in jax.tree_util.tree_leaves(
        state.delivered.actor_params))
    assert not all(np.isfinite(x).all() for x in jax.tree_util.tree_leaves(state.sac))
    assert train_script.main(["--resume", diverging]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: --resume={diverging}: the state at step 3000 holds a "
                          "non-finite critic_") and "\n" not in err, err
    assert run_checkpoint.saved_steps(diverging) == [2000, 3000]  # nothing written


def test_a_damaged_wandb_json_is_refused_on_resume_naming_it(runs, capsys):
    damaged = str(runs["root"] / "damaged-wandb")
    shutil.copytree(runs["interrupted"], damaged)
    path = os.path.join(damaged, tracking.WANDB_JSON)
    for text in ('{"id": "abc", "proj', '["a list"]'):
        with open(path, "w") as f:
            f.write(text)
        assert train_script.main(["--resume", damaged]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"error: {path}: not readable (") and err.count("\n") == 1, err
    assert run_checkpoint.saved_steps(damaged) == run_checkpoint.saved_steps(runs["interrupted"])


def test_track_without_wandb_ends_with_one_line_and_writes_nothing(tmp_path, capsys,
                                                                   monkeypatch):
    """wandb is an optional extra: where it cannot be imported (as the finder reports here),
    `--track` says what to install, exit 2, before anything is written."""
    find_spec = tracking.importlib.util.find_spec
    monkeypatch.setattr(tracking.importlib.util, "find_spec",
                        lambda name, *a: None if name == "wandb" else find_spec(name, *a))
    out = tmp_path / "run"
    assert train_script.main(["--track", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err == ('error: --track: needs wandb, which is not installed: pip install -e '
                   '".[track]" (or pip install wandb)\n'), err
    assert os.listdir(tmp_path) == []


def test_w_and_b_failing_ends_the_run_in_one_line_keeping_its_checkpoint(tmp_path, capsys,
                                                                         offline_wandb,
                                                                         monkeypatch):
    """W&B's start failing on its thread (as online without a login does) ended the run with
    a traceback; it is one line, exit 1, at the first point: the new run's directory, which
    holds no checkpoint yet, is removed."""
    pytest.importorskip("wandb")

    def no_login(self, *args):
        raise RuntimeError("api_key not configured (no-tty). call wandb.login(key=...)")

    monkeypatch.setattr(tracking.WandbRun, "_start", no_login)
    out = str(tmp_path / "tracked")
    assert train_script.main(RUN + ["--out", out, "--track"]) == 1
    err = capsys.readouterr().err
    assert err == ("error: W&B: api_key not configured (no-tty). call wandb.login(key=...); "
                   f"{out} removed\n"), err
    assert not os.path.exists(out)


def test_w_and_b_failing_as_it_ends_warns_in_one_line_and_keeps_the_finished_run(
        tmp_path, capsys, offline_wandb, monkeypatch):
    """W&B failing as it ends its record (its summary, the upload) came after the run and its
    result files, and raised a traceback over a finished run: it is a one-line warning, and
    the run's exit code and files stand."""
    pytest.importorskip("wandb")

    finish = tracking.WandbRun._finish

    def upload_fails(self, summary, exit_code):  # after ending the record, as an upload would
        finish(self, summary, exit_code)
        raise RuntimeError("upload failed: network unreachable")

    monkeypatch.setattr(tracking.WandbRun, "_finish", upload_fails)
    out = str(tmp_path / "tracked")
    assert train_script.main(RUN + ["--out", out, "--track"]) == 0
    err = capsys.readouterr().err
    assert err == ("warning: W&B: upload failed: network unreachable; the run's results are "
                   f"in {out}\n"), err
    assert run_dir.results_written(out)
    assert json.load(open(os.path.join(out, "summary.json")))["status"] == "finished"


def test_a_resumed_tracked_run_logs_the_points_w_and_b_holds_once(tmp_path, offline_wandb):
    """Stopped by SIGINT at its first point, a tracked run ends its W&B run cleanly, with that
    point logged; its checkpoint holds the point too, and the resumed run, which starts from
    the checkpoint's points, logs only the later ones: each step once over the two logs."""
    pytest.importorskip("wandb")
    out = str(tmp_path / "tracked")
    assert interrupted_main(train_script, RUN + ["--out", out, "--track"]) == 130
    run_id = tracking.load_settings(out)["id"]
    assert [wandb_records.steps(p) for p in wandb_records.logs(offline_wandb, run_id)] == [
        [2000]]
    assert train_script.main(["--resume", out]) == 0
    logs = wandb_records.logs(offline_wandb, run_id)
    assert [wandb_records.steps(p) for p in logs] == [[2000], [3000, 4000]]
    assert wandb_records.summary(logs[0])["status"] == "interrupted"
    assert wandb_records.summary(logs[1])["status"] == "finished"


def test_run_as_a_script_it_freezes_its_imports_and_imported_it_leaves_the_collector_alone():
    """Run as a script, train.py imports its modules with Python's cyclic collector off, then
    freezes what they made and turns the collector back on (its comment has the figures).
    Imported, as tests and benchmarks do, it changes neither."""
    code = """import gc, runpy, sys
sys.argv = ["train.py", "--help"]
try:
    runpy.run_path("scripts/train.py", run_name=sys.argv[1])
except SystemExit:
    pass
print("collector", gc.isenabled(), gc.get_freeze_count() > 0)"""
    for run_name, frozen in (("__main__", True), ("train", False)):
        out = subprocess.run([sys.executable, "-c", code.replace("sys.argv[1]", repr(run_name))],
                             capture_output=True, text=True, cwd=ROOT)
        assert out.returncode == 0, out.stderr[-3000:]
        assert out.stdout.splitlines()[-1] == f"collector True {frozen}", out.stdout[-500:]
