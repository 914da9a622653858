"""benchmarks/delivered.py --cold N: N runs, each from a cache directory of its own, reported
by their medians (a run never solved counts as never) with every run kept."""

from __future__ import annotations

import os
import sys

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
                        lambda run, seeds, episodes: [990.0 if run.endswith("/cold1") else 1000.0])
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
