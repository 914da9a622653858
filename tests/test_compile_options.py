"""benchmarks/compile_options.py: each variant runs cold, then warm from the cache the cold run
filled, with its XLA flags added to the caller's; a variant whose run fails is recorded with
the error and the others go on."""

from __future__ import annotations

from benchmarks import compile_options


def summary(**fields):
    base = {"startup_s": 1.0, "compile_s": 2.0, "run_s": 3.0, "solved_wall_s": [2.5],
            "solved_process_s": [5.5], "process_wall_s": 6.0, "delivered_return": [1000.0]}
    return dict(base, **fields)


def test_a_variant_runs_cold_then_warm_on_one_cache_with_its_flags_added(monkeypatch, tmp_path):
    calls = []

    def train(out, *flags, cache_dir=None, env=None):
        calls.append((out, flags, cache_dir, env["XLA_FLAGS"]))
        return summary(compile_s=9.0 if len(calls) == 1 else 1.0)

    monkeypatch.setattr(compile_options, "train", train)
    monkeypatch.setenv("XLA_FLAGS", "--xla_a=1")
    row = compile_options.measure("--xla_b=2", str(tmp_path), ["--seed=3"])
    assert [c[0].rsplit("/", 1)[1] for c in calls] == ["cold", "warm"]
    assert calls[0][2] == calls[1][2] and calls[0][0] != calls[1][0]
    assert {c[1] for c in calls} == {("--seed=3",)}
    assert {c[3] for c in calls} == {"--xla_a=1 --xla_b=2"}
    assert row["xla_flags"] == "--xla_b=2"
    assert (row["cold"]["compile_s"], row["warm"]["compile_s"]) == (9.0, 1.0)
    assert row["warm"]["solved_wall_s"] == 2.5 and row["warm"]["delivered_return"] == 1000.0


def test_a_failing_variant_is_recorded_with_its_error(monkeypatch, tmp_path):
    def train(out, *flags, cache_dir=None, env=None):
        raise SystemExit("train.py failed:\nUnknown flag in XLA_FLAGS: --xla_nope")

    monkeypatch.setattr(compile_options, "train", train)
    monkeypatch.delenv("XLA_FLAGS", raising=False)
    row = compile_options.measure("--xla_nope", str(tmp_path), [])
    assert "Unknown flag in XLA_FLAGS: --xla_nope" in row["error"]
    assert "cold" not in row and "warm" not in row
