"""The evaluation points of a benchmark's training run, with a line of progress at most every
`every_s` seconds: a device job killed at its time limit still shows how far it got; and
whether a run's reach of a return holds on fresh episodes."""

from __future__ import annotations

import time
from typing import Callable, List, Sequence, Tuple

Point = Tuple[int, float, float, float]
"""(env steps, kept score averaged over seeds, fraction of seeds stopped, seconds since the
recorder was made)."""


def recorder(label: str, every_s: float = 30.0) -> Tuple[List[Point], Callable]:
    """(points, on_point): `on_point` is `run_training`'s callback; it appends to `points`."""
    points: List[Point] = []
    start = time.time()
    shown = [start]

    def on_point(step, means, _returns, _elapsed):
        now = time.time()
        points.append((int(step), float(means["delivered_return"]), float(means["stopped"]),
                       now - start))
        if now - shown[0] >= every_s:
            shown[0] = now
            print(f"{label}: {int(step):,} steps after {now - start:.0f} s, kept score "
                  f"{points[-1][1]:.1f} on average, {points[-1][2]:.0%} of seeds stopped",
                  flush=True)

    return points, on_point


def reach_holds(fresh: Sequence[float], target: float) -> bool:
    """Whether a run whose seeds all reached `target` by their kept scores holds it on fresh
    episodes: every seed's delivered actor scores at least `target` there (`fresh`: one mean
    return per seed), as a reach asks every seed's kept score to."""
    return min(fresh) >= target
