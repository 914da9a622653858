"""Candidate settings for a preset, side by side: each variant trains `--seeds` seeds vmapped
in one run, one variant after another in one process, and reports what its seeds deliver.

A variant is a preset with fields replaced, given as JSON (`--variant '{"critic_layer_norm":
true}'`, repeatable; `{}` is the preset itself). Per variant: the delivered return (confirmed,
`sac_jax.selection`) of every seed at the end, the mean curve of delivered returns over the
evaluation points, the wall time (compilation included) and the run's environment steps.
Each seed's delivered actor is also scored over `--fresh-episodes` episodes no training
evaluation drew (`fresh`), the return it delivers, against which its kept score can be read.
Stopping is off unless the variant sets it, so every seed uses the whole budget; with
`--target R` each seed stops once its delivered actor's kept score is at R (over the
variant's `stop_measurements`), and a row also records when all its seeds had (`all_reached`:
env steps and seconds, compilation included).

    python -m benchmarks.preset_search --preset CartpoleSwingup --seeds 8 \\
        --variant '{}' --variant '{"critic_layer_norm": true}'

Writes benchmarks/results/preset_search-TASK-KIND.json, TASK the first variant's environment
(its name after "playground/"), with the command, machine, versions and date.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from benchmarks.fresh_episodes import fresh_returns
from benchmarks.points import recorder
from benchmarks.provenance import provenance, result_name, write_result
from sac_jax.presets import PRESETS
from sac_jax.run import run_training


def run_variant(config, seeds: int, seed: int, fresh_episodes: int, label: str = "") -> dict:
    points, on_point = recorder(label)
    t0 = time.time()
    result = run_training(config, seeds=seeds, seed=seed, on_point=on_point)
    wall_s = round(time.time() - t0, 1)
    reached = [dict(env_steps=step, seconds=round(seconds, 1))
               for step, _, stopped, seconds in points if stopped == 1.0][:1]
    delivered = np.asarray(result.summary["delivered_return"], np.float64)
    fresh = fresh_returns(config, result.state.delivered.actor_params, fresh_episodes)
    return dict(wall_s=wall_s, env_steps=points[-1][0],
                fresh_episodes=fresh_episodes, fresh=[round(f, 1) for f in fresh],
                fresh_mean=round(float(np.mean(fresh)), 1),
                delivered=[round(float(d), 1) for d in delivered],
                delivered_mean=round(float(delivered.mean()), 1),
                delivered_min=round(float(delivered.min()), 1),
                all_reached=reached[0] if reached else None,
                curve=[(step, round(kept, 1), round(seconds, 1))
                       for step, kept, _, seconds in points])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--preset", required=True, choices=sorted(PRESETS))
    parser.add_argument("--variant", action="append", type=json.loads, required=True,
                        help="JSON object of fields to replace (repeatable)")
    parser.add_argument("--seeds", type=int, default=8)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--fresh-episodes", type=int, default=100,
                        help="episodes scoring each seed's delivered actor at the end")
    parser.add_argument("--target", type=float, default=None,
                        help="stop each seed once its delivered actor's kept score is at this "
                             "return; record when all seeds had")
    args = parser.parse_args()
    source = provenance()
    base = PRESETS[args.preset].replace(stop_when_solved=args.target is not None,
                                        stop_return=args.target)
    configs = [base.replace(**v) for v in args.variant]  # all validated before any run
    rows = []
    for variant, config in zip(args.variant, configs):
        row = dict(variant=variant, **run_variant(config, args.seeds, args.seed,
                                                  args.fresh_episodes, json.dumps(variant)))
        rows.append(row)
        print(f"{json.dumps(variant)}: delivered mean {row['delivered_mean']}, min "
              f"{row['delivered_min']} (fresh episodes: mean {row['fresh_mean']}, per seed "
              f"{row['fresh']}) after "
              f"{row['env_steps']:,} steps, {row['wall_s']} s, all at the target "
              f"{row['all_reached']}; "
              f"curve {row['curve'][::max(1, len(row['curve']) // 8)]}", flush=True)
    task = configs[0].env.split("/")[-1]  # the first variant's environment names the file
    write_result(result_name(f"preset_search-{task}"),
                 dict(preset=args.preset, seeds=args.seeds, target=args.target, rows=rows),
                 source)


if __name__ == "__main__":
    main()
