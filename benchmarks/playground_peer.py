"""MuJoCo Playground's own SAC against ours on a Playground task, back to back in one process.

(a) The peer: Brax's `sac.train` with Playground's tuned `brax_sac_config(task)` (128 envs,
    batch 512, 8 updates per step, lr 1e-3, observation normalisation, critic layer norm, 5M or
    10M steps), on `registry.load(task, {"impl": "jax"})` under Playground's own
    `wrap_for_brax_training`, as Playground's training notebook runs it. Brax 0.14.2 rejects
    the config's `num_resets_per_eval`, which is dropped; its `network_factory` settings go to
    `make_sac_networks`. `--peer-steps` shortens its budget (recorded).
(b) Ours: `run_training` on `playground/<task>` with the task's preset (or `--preset`, with
    `--variant`'s fields replaced), its budget `--total-steps`, stopping each seed once its
    delivered actor's kept score reaches the peer's final return plus `--stop-margin` (over
    the preset's `stop_measurements`), for 1 seed and for `--seeds` seeds vmapped in one
    program. The margin is there because a kept
    score is a mean over a few dozen episodes: a seed stopping the moment it reaches the
    peer's return delivers an actor whose fresh mean is as often just below it as above.
    With `--runs N` (odd) the one-seed side is N separate runs, of seeds `--seed` to
    `--seed` + N - 1, and its figures are the median run's (by time to the return, a run
    that never reaches it counting as the slowest; runs after the first reuse its compiled
    programs and count its build time as theirs): one seed's time is a draw (CartpoleSwingup's
    seed 0 reached 861.1 in 328,704 steps in one H200 run and stayed at 853.6 for 1,623,040 in
    the next, where 9 of 16 vmapped seeds reached 859.9 within 345,088).
    `--peer-from FILE` takes (a) from an earlier result of the same task instead of running it
    (recorded as `peer_from`: the file's command, date, machine and versions), for when both
    sides do not fit one job's time limit, on a machine of the earlier job's device kind.
    With `--runs 0` the one-seed side comes from that file too (recorded as `one_seed_from`),
    measured beside the peer with the same preset, variant, seed, budget and margin, and this
    job runs only `--seeds` seeds: for when even ours' two sides do not fit one job
    (AcrobotSwingup's).

Per run: wall time from the trainer's call, the evaluation points (env steps, return, seconds),
and for ours the seconds and env steps at which every seed's delivered actor had reached the
peer's final evaluation return by its kept score (`to_peer_final`), and each delivered actor's
mean return over `--fresh-episodes` episodes no training evaluation drew (`fresh`; a stopped
seed's actor is the one it stopped with). A reach holds (`reach_holds`, None where not
reached) only if every seed's delivered actor scores the peer's return on fresh episodes too
(`benchmarks.points.reach_holds`; before 2026-11-30 the seeds' mean had to). The issue-24
targets: ours reaches it in at most 1/3 of the peer's wall time, and `--seeds` seeds in at most
2x one seed's time.

    python -m benchmarks.playground_peer --task CartpoleBalance
    python -m benchmarks.playground_peer --task CartpoleBalance --quick   # checks the script

Writes benchmarks/results/playground_peer-TASK-KIND.json (command, machine, versions, date).
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import sys
import time

import jax
import numpy as np

from benchmarks.brax_peer import device_put_replicated
from benchmarks.fresh_episodes import fresh_returns
from benchmarks.points import reach_holds, recorder
from benchmarks.provenance import provenance, result_name, write_result
from envs import playground
from sac_jax.presets import PRESETS
from sac_jax.run import run_training

REJECTED = ("num_resets_per_eval",)  # in brax_sac_config, not an argument of brax 0.14.2's train


def peer_arguments(task: str, peer_steps=None) -> dict:
    """`sac.train` keyword arguments from Playground's `brax_sac_config(task)`."""
    from brax.training.agents.sac import networks as sac_networks
    from mujoco_playground.config import dm_control_suite_params

    config = dm_control_suite_params.brax_sac_config(task).to_dict()
    for key in REJECTED:
        config.pop(key, None)
    config["network_factory"] = functools.partial(sac_networks.make_sac_networks,
                                                  **config["network_factory"])
    if peer_steps is not None:
        config["num_timesteps"] = peer_steps
    return config


def run_peer(task: str, arguments: dict, seed: int) -> dict:
    from brax.training.agents.sac import train as brax_sac
    from mujoco_playground import registry, wrapper

    env = registry.load(task, config_overrides={"impl": "jax"})
    points = []
    t0 = time.time()

    def progress(step, metrics):
        points.append((int(step), float(metrics["eval/episode_reward"]), time.time() - t0))
        print(f"  peer {task} step {step:,}: {points[-1][1]:.1f} at {points[-1][2]:.1f} s",
              file=sys.stderr, flush=True)

    brax_sac.train(environment=env, seed=seed, progress_fn=progress,
                   wrap_env_fn=wrapper.wrap_for_brax_training, **arguments)
    return dict(wall_s=round(time.time() - t0, 2), points=points, final_return=points[-1][1])


def _earlier(path: str, task: str):
    """(result, provenance) of an earlier playground_peer result file of `task`, measured on
    a device of this machine's kind (where the file names one): a ratio of times from two
    jobs compares like with like only there."""
    try:
        with open(path) as f:
            earlier = json.load(f)
        result, source = earlier["result"], earlier["provenance"]
        run = result["task"], result["peer"], result["peer_arguments"], result["peer_network"]
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise ValueError(f"--peer-from {path} is not a playground_peer result "
                         f"({type(error).__name__}: {error})") from None
    if run[0] != task:
        raise ValueError(f"--peer-from {path} is a run of {run[0]}, not {task}")
    machine, here = source.get("machine") or {}, jax.devices()[0].device_kind
    if machine.get("device_kind", here) != here:
        raise ValueError(f"--peer-from {path} was measured on a {machine['device_kind']}, "
                         f"not this machine's {here}")
    return result, dict(file=os.path.basename(path), command=source.get("command"),
                        date=source.get("date"), machine=machine,
                        versions=source.get("versions"))


def earlier_peer(path: str, task: str):
    """(peer run, its `sac.train` arguments, its network settings, `peer_from` provenance) from
    an earlier playground_peer result file of `task`: the job that ran the peer, which is the
    file's own `peer_from` where that file took its peer from another."""
    result, source = _earlier(path, task)
    return (result["peer"], result["peer_arguments"], result["peer_network"],
            result.get("peer_from") or source)


def earlier_one_seed(path: str, task: str, expected: dict):
    """(one-seed run, the single runs' summaries, `one_seed_from` provenance) from an earlier
    playground_peer result file of `task`, for `--runs 0`: its fields `expected` names (preset,
    variant, seed, budget, stop margin) must hold the values given."""
    result, source = _earlier(path, task)
    differs = [f"{key} {result.get(key)!r}, not {value!r}" for key, value in expected.items()
               if result.get(key) != value]
    if differs or "1" not in result.get("ours", {}):
        raise ValueError(f"--runs 0: --peer-from {path} has no one-seed run of this "
                         f"configuration ({'; '.join(differs) or 'no one-seed run'})")
    return result["ours"]["1"], result["single_runs"], result.get("one_seed_from") or source


def run_ours(config, seeds: int, seed: int, target: float, fresh_episodes: int,
             margin: float = 0.0, build_s=None) -> dict:
    """`seeds` seeds vmapped; each stops once its delivered actor's kept score is at `target`
    + `margin`. Points: (env steps, delivered return averaged over seeds, fraction stopped,
    seconds). The reach holds where every delivered actor's fresh mean is at `target`.
    `build_s`: the seconds to count for building the programs instead of this run's own
    (`own_build_s`), for a run that reuses an earlier run's compiled programs: its seconds
    are then those of a run that compiled as that one did (`wall_s` stays as measured)."""
    config = config.replace(stop_when_solved=True, stop_return=target + margin)
    built = []
    points, on_point = recorder(f"ours, {seeds} seed(s)")
    t0 = time.time()
    result = run_training(config, seeds=seeds, seed=seed, on_ready=built.append,
                          on_point=on_point)
    wall_s = round(time.time() - t0, 2)
    shift = 0.0 if build_s is None else build_s - built[0]
    points = [(s, r, stopped, t + shift) for s, r, stopped, t in points]
    reached = next(((s, t) for s, _, stopped, t in points if stopped == 1.0), None)
    fresh = fresh_returns(config, result.state.delivered.actor_params, fresh_episodes)
    return dict(seeds=seeds, seed=seed, wall_s=wall_s, own_build_s=round(built[0], 2),
                build_s=round(built[0] + shift, 2), points=points,
                to_peer_final=None if reached is None else
                dict(env_steps=reached[0], seconds=round(reached[1], 2)),
                fresh_episodes=fresh_episodes, fresh=[round(f, 1) for f in fresh],
                reach_holds=None if reached is None else reach_holds(fresh, target))


def median_run(runs: list) -> dict:
    """The median of an odd number of runs by seconds to the peer's return (unreached: last)."""
    def seconds(run):
        return float("inf") if run["to_peer_final"] is None else run["to_peer_final"]["seconds"]
    return sorted(runs, key=seconds)[len(runs) // 2]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--task", default="CartpoleBalance", choices=playground.TASKS)
    parser.add_argument("--preset", default=None, help="ours (default: the task's preset)")
    parser.add_argument("--variant", type=json.loads, default={}, metavar="JSON",
                        help="ours: a JSON object of the preset's fields to replace, e.g. "
                             "'{\"num_envs\": 128}' (recorded)")
    parser.add_argument("--seeds", type=int, default=16, help="ours, vmapped in one run")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--total-steps", type=int, default=102_400,
                        help="ours: the budget (and replay size) within which to reach the "
                             "peer's final return")
    parser.add_argument("--peer-steps", type=int, default=None,
                        help="the peer's budget (default: its config's num_timesteps)")
    parser.add_argument("--peer-from", default=None, metavar="FILE",
                        help="take the peer's run from this earlier playground_peer result of "
                             "the same task instead of running it")
    parser.add_argument("--runs", type=int, default=1,
                        help="ours: separate one-seed runs (odd), of seeds --seed onwards; "
                             "the median run is the one-seed figure; 0: take the one-seed "
                             "side from --peer-from's file too")
    parser.add_argument("--stop-margin", type=float, default=0.0, metavar="POINTS",
                        help="ours: stop a seed at the peer's final return plus this")
    parser.add_argument("--fresh-episodes", type=int, default=100,
                        help="episodes scoring each seed's delivered actor at the end")
    parser.add_argument("--quick", action="store_true", help="tiny runs (figures meaningless)")
    args = parser.parse_args()
    if not args.stop_margin >= 0:
        parser.error(f"--stop-margin must be >= 0, got {args.stop_margin}")
    if args.runs < 0 or args.runs % 2 == 0 and not (args.runs == 0 and args.peer_from):
        parser.error(f"--runs must be an odd number >= 1 (or 0 with --peer-from), "
                     f"got {args.runs}")
    source = provenance()
    preset = args.preset or args.task
    if preset not in PRESETS:
        parser.error(f"no preset {preset!r}; give --preset (one of {sorted(PRESETS)})")
    try:
        config = PRESETS[preset].replace(**{**args.variant, "env": playground.PREFIX + args.task,
                                            "total_steps": args.total_steps,
                                            "buffer_size": args.total_steps})
    except (TypeError, ValueError) as error:
        parser.error(f"--variant {json.dumps(args.variant)}: {error}")
    if args.quick:
        config = config.replace(total_steps=3072, buffer_size=3072, eval_every=1024)
    if args.peer_from:
        try:
            peer, arguments, network, peer_from = earlier_peer(args.peer_from, args.task)
        except ValueError as error:
            parser.error(str(error))
    else:
        arguments = peer_arguments(args.task, 20_000 if args.quick else args.peer_steps)
        if args.quick:
            arguments.update(num_envs=16, batch_size=64, min_replay_size=1024, num_evals=2,
                             num_eval_envs=4, grad_updates_per_step=1)
        network, peer_from = dict(arguments["network_factory"].keywords), None
        if not hasattr(jax, "device_put_replicated"):  # Brax 0.14.2 calls it; gone in JAX 0.10
            jax.device_put_replicated = device_put_replicated
        peer = run_peer(args.task, arguments, args.seed)
    settings = dict(task=args.task, preset=preset, variant=args.variant, quick=args.quick,
                    seed=args.seed, stop_margin=args.stop_margin, total_steps=config.total_steps)
    one_seed_from = None
    if args.runs == 0:  # the one-seed side ran with the peer: --seeds seeds' run is this job's
        try:
            one_run, single_runs, one_seed_from = earlier_one_seed(args.peer_from, args.task,
                                                                   settings)
        except ValueError as error:
            parser.error(str(error))
    target = peer["final_return"]
    if args.runs:
        # the first run compiles; the others reuse its programs and count its build time
        singles = [run_ours(config, 1, args.seed, target, args.fresh_episodes,
                            args.stop_margin)]
        singles += [run_ours(config, 1, args.seed + i, target, args.fresh_episodes,
                             args.stop_margin, build_s=singles[0]["build_s"])
                    for i in range(1, args.runs)]
        one_run = median_run(singles)
        single_runs = [dict(seed=run["seed"], to_peer_final=run["to_peer_final"],
                            fresh_mean=round(float(np.mean(run["fresh"])), 1),
                            reach_holds=run["reach_holds"]) for run in singles]
    ours = {1: one_run}
    if args.seeds > 1:
        ours[args.seeds] = run_ours(config, args.seeds, args.seed, target, args.fresh_episodes,
                                    args.stop_margin)
    one = ours[1]["to_peer_final"]
    many = ours[args.seeds]["to_peer_final"]
    result = dict(
        **settings,
        peer_arguments={k: v for k, v in arguments.items() if k != "network_factory"},
        peer_network=network, peer=peer, peer_from=peer_from,
        ours={str(n): run for n, run in ours.items()},
        single_runs=single_runs, one_seed_from=one_seed_from,
        ours_over_peer_time=None if one is None else round(one["seconds"] / peer["wall_s"], 3),
        seeds_over_one_time=(None if None in (one, many)
                             else round(many["seconds"] / one["seconds"], 3)))
    print(f"{args.task}: peer final {target:.1f} in {peer['wall_s']:.0f} s; ours 1 seed "
          f"{one}; {args.seeds} seeds {many}; time ratio {result['ours_over_peer_time']}, "
          f"seeds ratio {result['seeds_over_one_time']}; delivered actors' fresh means "
          + ", ".join(f"{n} seed(s) {np.mean(run['fresh']):.1f}" for n, run in ours.items()))
    write_result(result_name(f"playground_peer-{args.task}"), result, source)


if __name__ == "__main__":
    main()
