"""Does every preset deliver? Trains N seeds of each named configuration in one run each, as a
user does (`scripts/train.py --preset NAME --seeds N`, in its own process), and scores every
seed's saved policy (`sac_jax.load_policy` of the run directory) over 10 episodes of
Gymnasium's twin of the task (our environment, from fresh initial states, where Gymnasium has
no twin: the Bullet-style pendulum of `v1`), against the task's solved return
(`benchmarks.delivered`'s scorers). Before 2026-11-30 it scored the delivered actors of
`run_training` in this process, not what a run saves.

    python -m benchmarks.presets_delivered          # cleanrl, pendulum, v1, double-pendulum
    python -m benchmarks.presets_delivered --runs pendulum --seeds 2

Writes benchmarks/results/NAME.json (`--name`, default presets_delivered-KIND:
presets_delivered-h100; command, machine, versions, date, every seed's score).
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time

import envs
import sac_jax
from benchmarks.delivered import scorer, train
from benchmarks.provenance import provenance, result_name, write_result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", nargs="+", choices=sorted(sac_jax.PRESETS),
                        default=["cleanrl", "pendulum", "v1", "double-pendulum"])
    parser.add_argument("--seeds", type=int, default=4)
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--name", default=None, help="results file benchmarks/results/NAME.json "
                        "(default presets_delivered-KIND: presets_delivered-h100)")
    args = parser.parse_args()
    source = provenance()
    root = tempfile.mkdtemp(prefix="presets-")
    results = {}
    for name in args.runs:
        config = sac_jax.PRESETS[name]
        out = os.path.join(root, name)
        start = time.perf_counter()
        summary = train(out, "--preset", name, "--seeds", str(args.seeds))
        judge = "gymnasium" if envs.spec(config.env).gymnasium_id else "ours"
        scores = scorer(judge)(out, args.seeds, args.episodes)  # the saved policies
        threshold = envs.spec(config.env).solved_return
        results[name] = {
            "env": config.env, "judged_in": judge, "threshold": threshold, "scores": scores,
            "solved": sum(s >= threshold for s in scores), "seeds": args.seeds,
            "delivered_return": summary["delivered_return"],
            "delivered_at_step": summary["delivered_at_step"],
            "last_eval_return": summary["eval_return"],
            "run_steps": config.run_steps, "confirm_episodes": config.confirm_episodes,
            "seconds": round(time.perf_counter() - start, 1)}
        print(json.dumps({name: results[name]}), flush=True)
    write_result(args.name or result_name("presets_delivered"), results, source)


if __name__ == "__main__":
    main()
