"""benchmarks/playground_peer.py without a GPU: `--peer-from` (the peer's run taken from an
earlier result file of the same task, with its provenance kept, and with `--runs 0` the one-seed
side too), ours stopping at the peer's
return plus `--stop-margin`, the median of `--runs` single-seed runs and the build time they
share, and a one-line error for every bad flag or file."""

from __future__ import annotations

import json
import sys
import types

import pytest

from benchmarks import playground_peer, points

PEER = {"wall_s": 274.18, "points": [[0, 3.1, 28.7], [10_000_640, 65.9, 273.1]],
        "final_return": 65.9}


def write_earlier(path, task="AcrobotSwingup", **result):
    path.write_text(json.dumps({
        "provenance": {"command": f"python -m benchmarks.playground_peer --task {task}",
                       "date": "2026-11-27T17:44:50+00:00", "machine": {}},
        "result": {"task": task, "peer": PEER, "peer_arguments": {"num_timesteps": 10_000_000},
                   "peer_network": {"q_network_layer_norm": True}, **result}}))
    return str(path)


def test_the_peer_run_and_its_provenance_come_from_the_earlier_file(tmp_path):
    path = write_earlier(tmp_path / "playground_peer-AcrobotSwingup-h100.json")
    peer, arguments, network, source = playground_peer.earlier_peer(path, "AcrobotSwingup")
    assert peer == PEER
    assert arguments == {"num_timesteps": 10_000_000}
    assert network == {"q_network_layer_norm": True}
    assert source == {"file": "playground_peer-AcrobotSwingup-h100.json",
                      "command": "python -m benchmarks.playground_peer --task AcrobotSwingup",
                      "date": "2026-11-27T17:44:50+00:00", "machine": {}, "versions": None}


def test_a_peer_taken_from_a_file_that_took_it_from_another_names_the_job_that_ran_it(tmp_path):
    first = write_earlier(tmp_path / "first.json")
    second = tmp_path / "second.json"
    earlier = json.loads((tmp_path / "first.json").read_text())
    earlier["provenance"]["date"] = "2026-11-28T00:32:06+00:00"
    earlier["result"]["peer_from"] = playground_peer.earlier_peer(first, "AcrobotSwingup")[3]
    second.write_text(json.dumps(earlier))
    source = playground_peer.earlier_peer(str(second), "AcrobotSwingup")[3]
    assert source["file"] == "first.json" and source["date"] == "2026-11-27T17:44:50+00:00"


@pytest.mark.parametrize("content, message", [
    (None, "is a run of CartpoleSwingup, not AcrobotSwingup"),
    ('{"result": {"task": "AcrobotSwingup"}}', "is not a playground_peer result (KeyError: "),
    ("not json", "is not a playground_peer result (JSONDecodeError: "),
    ("missing", "is not a playground_peer result (FileNotFoundError: "),
    ("gpu", "was measured on a NVIDIA H200, not this machine's cpu"),
])
def test_a_file_of_another_task_or_no_result_fails_in_one_line(tmp_path, monkeypatch, capsys,
                                                                content, message):
    path = tmp_path / "earlier.json"
    if content is None:
        write_earlier(path, task="CartpoleSwingup")
    elif content == "gpu":  # a ratio of times needs both jobs on one device kind
        write_earlier(path)
        earlier = json.loads(path.read_text())
        earlier["provenance"]["machine"] = {"device_kind": "NVIDIA H200"}
        path.write_text(json.dumps(earlier))
    elif content != "missing":
        path.write_text(content)
    monkeypatch.setattr(sys, "argv", ["playground_peer.py", "--task", "AcrobotSwingup",
                                      "--peer-from", str(path)])
    with pytest.raises(SystemExit) as raised:
        playground_peer.main()
    assert raised.value.code == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.startswith(f"playground_peer.py: error: --peer-from {path} ")
    assert message in last


def fake_training(seen, build_s, reached_s):
    """run_training's stand-in: building takes `build_s` and the one point, where every seed
    has stopped, comes `reached_s` after the call, on a clock it advances (`seen["now"]`)."""
    def training(config, seeds, seed, on_ready, on_point):
        seen["stop_return"] = config.stop_return
        seen["now"] += build_s
        on_ready(build_s)
        seen["now"] += reached_s - build_s
        on_point(1024, {"delivered_return": 863.0, "stopped": 1.0}, None, 0.0)
        return type("Result", (), {"state": type("State", (), {"delivered": type(
            "Delivered", (), {"actor_params": None})})})
    return training


@pytest.fixture
def clock(monkeypatch):
    seen = {"now": 0.0}
    fake = types.SimpleNamespace(time=lambda: seen["now"])
    monkeypatch.setattr(playground_peer, "time", fake)
    monkeypatch.setattr(points, "time", fake)
    return seen


def test_ours_stops_at_the_peer_return_plus_the_margin_and_holds_only_at_the_return(
        monkeypatch, clock):
    """A seed stops at target + margin, but its reach holds where its fresh mean is at the
    target itself (the peer's return), not at target + margin."""
    monkeypatch.setattr(playground_peer, "run_training", fake_training(clock, 20.0, 30.0))
    for fresh, holds in ((861.0, True), (860.9, False)):
        monkeypatch.setattr(playground_peer, "fresh_returns", lambda *_, f=fresh: [f])
        run = playground_peer.run_ours(playground_peer.PRESETS["CartpoleSwingup"], 1, 0,
                                       target=861.0, fresh_episodes=1, margin=2.0)
        assert clock["stop_return"] == 863.0
        assert run["to_peer_final"] == {"env_steps": 1024, "seconds": 30.0}
        assert run["reach_holds"] is holds


def test_a_run_reusing_compiled_programs_counts_the_given_build_time(monkeypatch, clock):
    monkeypatch.setattr(playground_peer, "run_training", fake_training(clock, 0.5, 10.5))
    monkeypatch.setattr(playground_peer, "fresh_returns", lambda *_: [861.0])
    run = playground_peer.run_ours(playground_peer.PRESETS["CartpoleSwingup"], 1, 1,
                                   target=861.0, fresh_episodes=1, build_s=20.0)
    assert run["to_peer_final"]["seconds"] == 30.0 and run["points"][0][3] == 30.0
    assert (run["own_build_s"], run["build_s"], run["wall_s"]) == (0.5, 20.0, 10.5)


def test_the_one_seed_figure_is_the_median_run_an_unreached_run_counting_as_slowest():
    runs = [{"seed": seed, "to_peer_final": None if t is None else {"seconds": t}}
            for seed, t in ((0, None), (1, 40.0), (2, 35.0))]
    assert playground_peer.median_run(runs)["seed"] == 1
    assert playground_peer.median_run(runs[:1])["seed"] == 0
    assert playground_peer.median_run([runs[0], runs[0], runs[2]])["to_peer_final"] is None


@pytest.mark.parametrize("flags, error", [
    (["--stop-margin", "-1"], "--stop-margin must be >= 0, got -1.0"),
    (["--stop-margin", "nan"], "--stop-margin must be >= 0, got nan"),
    (["--runs", "0"], "--runs must be an odd number >= 1 (or 0 with --peer-from), got 0"),
    (["--runs", "2"], "--runs must be an odd number >= 1 (or 0 with --peer-from), got 2"),
    (["--runs", "-1"], "--runs must be an odd number >= 1 (or 0 with --peer-from), got -1"),
    (["--variant", '{"num_envz": 128}'],
     """--variant {"num_envz": 128}: SACConfig has no field(s) ['num_envz']"""),
    (["--variant", '{"num_envs": 0}'],
     '--variant {"num_envs": 0}: SACConfig.num_envs=0: must be a positive integer')])
def test_a_bad_flag_fails_in_one_line_before_anything_runs(monkeypatch, capsys, flags, error):
    monkeypatch.setattr(sys, "argv", ["playground_peer.py", *flags])
    with pytest.raises(SystemExit) as raised:
        playground_peer.main()
    assert raised.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        f"playground_peer.py: error: {error}")


ONE_SEED = {"seeds": 1, "seed": 0, "to_peer_final": {"env_steps": 4_096_000, "seconds": 60.0},
            "fresh": [70.0], "reach_holds": True}
SETTINGS = {"preset": "AcrobotSwingup", "variant": {}, "quick": False, "seed": 0,
            "stop_margin": 2.0, "total_steps": 8_192_000}
ONE_SEED_FLAGS = ["--task", "AcrobotSwingup", "--runs", "0", "--seeds", "16", "--stop-margin",
                  "2", "--total-steps", "8192000", "--fresh-episodes", "1"]


def test_runs_0_takes_the_one_seed_side_from_the_earlier_file_and_runs_only_the_seeds(
        tmp_path, monkeypatch, clock):
    path = write_earlier(tmp_path / "job1.json", ours={"1": ONE_SEED}, single_runs=[
        {"seed": 0, "to_peer_final": ONE_SEED["to_peer_final"]}], **SETTINGS)
    calls = []
    training = fake_training(clock, 20.0, 90.0)
    monkeypatch.setattr(playground_peer, "run_training",
                        lambda config, seeds, **kw: calls.append(seeds) or training(
                            config, seeds, **kw))
    monkeypatch.setattr(playground_peer, "fresh_returns", lambda *_: [70.0] * 16)
    monkeypatch.setenv("SAC_JAX_RESULTS_DIR", str(tmp_path / "out"))
    monkeypatch.setattr(sys, "argv", ["playground_peer.py", *ONE_SEED_FLAGS,
                                      "--peer-from", path])
    playground_peer.main()
    [written] = (tmp_path / "out").iterdir()
    result = json.loads(written.read_text())["result"]
    assert calls == [16]  # no one-seed run in this job
    assert result["ours"]["1"] == ONE_SEED and result["ours"]["16"]["seeds"] == 16
    assert result["one_seed_from"] == result["peer_from"] == {
        "file": "job1.json", "command": "python -m benchmarks.playground_peer --task "
        "AcrobotSwingup", "date": "2026-11-27T17:44:50+00:00", "machine": {},
        "versions": None}
    assert result["ours_over_peer_time"] == round(60.0 / PEER["wall_s"], 3)
    assert result["seeds_over_one_time"] == 1.5  # 90 s against the earlier job's 60 s


@pytest.mark.parametrize("earlier, message", [
    ({**SETTINGS, "total_steps": 4_096_000}, "(total_steps 4096000, not 8192000)"),
    ({**SETTINGS, "variant": {"num_envs": 128}, "stop_margin": 0.0},
     "(variant {'num_envs': 128}, not {}; stop_margin 0.0, not 2.0)"),
    (SETTINGS, "(no one-seed run)")])
def test_runs_0_with_a_file_of_another_configuration_fails_in_one_line(
        tmp_path, monkeypatch, capsys, earlier, message):
    ours = {} if earlier is SETTINGS else {"ours": {"1": ONE_SEED}}
    path = write_earlier(tmp_path / "job1.json", **earlier, **ours)
    monkeypatch.setattr(sys, "argv", ["playground_peer.py", *ONE_SEED_FLAGS,
                                      "--peer-from", path])
    with pytest.raises(SystemExit) as raised:
        playground_peer.main()
    assert raised.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        f"playground_peer.py: error: --runs 0: --peer-from {path} has no one-seed run of this "
        f"configuration {message}")
