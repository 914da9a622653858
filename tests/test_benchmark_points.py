"""benchmarks/points.py: every evaluation point recorded, a progress line at most every
`every_s` seconds; a reach held on fresh episodes."""

from __future__ import annotations

import types

from benchmarks import points


def test_every_point_is_recorded_and_progress_is_printed_at_most_every_interval(
        monkeypatch, capsys):
    now = {"t": 100.0}
    monkeypatch.setattr(points, "time", types.SimpleNamespace(time=lambda: now["t"]))
    recorded, on_point = points.recorder("ours", every_s=30.0)
    for step, t, stopped in ((1024, 110.0, 0.0), (2048, 135.0, 0.5), (3072, 140.0, 0.5),
                             (4096, 170.0, 1.0)):
        now["t"] = t
        on_point(step, {"delivered_return": step / 10, "stopped": stopped}, None, 0.0)
    assert recorded == [(1024, 102.4, 0.0, 10.0), (2048, 204.8, 0.5, 35.0),
                        (3072, 307.2, 0.5, 40.0), (4096, 409.6, 1.0, 70.0)]
    assert capsys.readouterr().out.splitlines() == [
        "ours: 2,048 steps after 35 s, kept score 204.8 on average, 50% of seeds stopped",
        "ours: 4,096 steps after 70 s, kept score 409.6 on average, 100% of seeds stopped"]


def test_a_reach_holds_only_where_every_seed_scores_it_on_fresh_episodes():
    """Two seeds whose fresh mean is at the target, one of them below it, do not hold it."""
    assert points.reach_holds([50.0, 40.0], 40.0)
    assert not points.reach_holds([50.0, 30.0], 40.0)
