"""benchmarks/delivered.py --cold N: N runs, each from a cache directory of its own, reported
by their medians (a run never solved counts as never) with every run kept."""

from __future__ import annotations

import os
import sys

import pytest

from benchmarks import delivered


def test_cold_runs_each_start_from_an_empty_cache_and_are_reported_by_their_medians(
        monkeypatch, tmp_path):
    colds = iter([(9.0, 12.0), (8.0, None), (10.0, 11.0)])  # (compile_s, solved_process_s)
    calls, written = [], {}
    is_cold = lambda out: os.path.basename(out).startswith("cold")

    def train(out, *flags, cache_dir=None, env=None):
        calls.append((out, cache_dir))
        compile_s, solved = next(colds) if is_cold(out) else (1.0, 5.0)
        return {"compile_s": compile_s, "solved_process_s": [solved], "solved_wall_s": [2.0],
                "solved_at_step": [7168], "delivered_return": [1000.0],
                "process_wall_s": compile_s + 3.0}

    monkeypatch.setattr(delivered, "train", train)
    monkeypatch.setattr(delivered, "gymnasium_scores",
                        lambda run, seeds, episodes, first=0: [990.0 if run.endswith("/cold1")
                                                               else 1000.0])
    monkeypatch.setattr(delivered, "write_result",
                        lambda name, result, provenance: written.update({name: result}))
    monkeypatch.setattr(delivered, "provenance", lambda: {})
    monkeypatch.setattr(delivered, "machine_kind", lambda: "cpu")
    monkeypatch.setattr(delivered.tempfile, "mkdtemp",
                        lambda prefix="", dir=None: str(tmp_path / f"{prefix}{len(calls)}"))
    monkeypatch.setattr(sys, "argv", ["delivered", "--seeds", "0", "--many", "0", "--cold", "3"])
    delivered.main()

    cold = written["delivered"]["cold"]
    assert [r["compile_s"] for r in cold["runs"]] == [9.0, 8.0, 10.0]
    assert cold["compile_s"] == 9.0 and cold["solved_process_s"] == 12.0  # None counts as never
    assert cold["gymnasium_return"] == 990.0  # the lowest
    cold_calls = [c for c in calls if is_cold(c[0])]
    assert len(cold_calls) == 3 and len({c[1] for c in cold_calls}) == 3
    assert all(c[1] is None for c in calls if not is_cold(c[0]))  # warm runs: the usual cache


def test_another_preset_trains_in_every_run_and_is_judged_in_its_own_task(monkeypatch, tmp_path):
    """--preset CartpoleBalance: every run passes the preset; a task with no Gymnasium twin is
    judged over fresh episodes of the task itself, against its solved return (900); each
    seed's run on episodes of its own (the cold run's seed is 0)."""
    calls, written, firsts = [], {}, []

    def train(out, *flags, cache_dir=None, env=None):
        calls.append(flags)
        return {"compile_s": 20.0, "solved_process_s": [30.0], "solved_wall_s": [8.0],
                "solved_at_step": [9216], "delivered_return": [999.0], "process_wall_s": 33.0}

    fresh = iter([950.0, 850.0, 990.0])
    monkeypatch.setattr(delivered, "train", train)
    monkeypatch.setattr(delivered, "gymnasium_scores", lambda *args: 1 / 0)
    monkeypatch.setattr(delivered, "our_scores", lambda run, seeds, episodes, first=0: (
        firsts.append(first), [next(fresh)])[1])
    monkeypatch.setattr(delivered, "write_result",
                        lambda name, result, provenance: written.update({name: result}))
    monkeypatch.setattr(delivered, "provenance", lambda: {})
    monkeypatch.setattr(delivered, "machine_kind", lambda: "cpu")
    monkeypatch.setattr(sys, "argv", ["delivered", "--preset", "CartpoleBalance", "--seeds", "0",
                                      "1", "--many", "0", "--cold", "1"])
    delivered.main()

    result = written["delivered-CartpoleBalance"]
    assert all(flags[:2] == ("--preset", "CartpoleBalance") for flags in calls) and len(calls) == 4
    assert result["judged_in"] == "ours" and result["solved_return"] == 900.0
    assert [r["fresh_return"] for r in result["runs"]] == [950.0, 850.0]
    assert result["warm"]["ours_at_least_900"] == 1
    assert result["cold"]["fresh_return"] == 990.0
    assert firsts == [0, 1, 0]


def test_judging_a_task_without_a_gymnasium_twin_in_gymnasium_fails_in_one_line(
        monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["delivered", "--preset", "CartpoleBalance",
                                      "--judge", "gymnasium"])
    with pytest.raises(SystemExit) as exit_:
        delivered.main()
    assert exit_.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        "delivered: error: --judge gymnasium: playground/CartpoleBalance has no Gymnasium twin")


def test_a_failed_training_process_is_one_error_its_memory_run_may_report(tmp_path):
    """`delivered.train` raises `TrainFailed` with the script's stderr; the memory benchmark's
    run that `may_fail` returns that stderr's last line instead (the script's own one-line
    error for a flag it does not know)."""
    from benchmarks import memory as memory_benchmark

    with pytest.raises(delivered.TrainFailed) as failed:
        delivered.train(str(tmp_path / "run"), "--no-such-flag")
    assert "--no-such-flag" in failed.value.stderr
    assert "failed:" in str(failed.value)
    result = memory_benchmark._peak(str(tmp_path / "run"), "--no-such-flag", may_fail=True)
    assert set(result) == {"failed"}
    assert result["failed"] == failed.value.stderr.strip().splitlines()[-1][:500]
