"""What the README's command delivers: for several `--seed` values, and for one run of many
seeds, the time to a solved delivered policy and that policy's return in the real environment.

    python -m benchmarks.delivered                       # seeds 0-9 one by one, then --seeds 32
    python -m benchmarks.delivered --seeds 0 1 2 --many 8 --cold 5
    python -m benchmarks.delivered --preset CartpoleBalance --many 0 --cold 5 --episodes 100

Each run is `python scripts/train.py --seed N --out DIR` (the README's first command, the
`fast` preset; `--preset NAME` adds `--preset NAME` to every run) in its own process, with the
compilation cache warm (a first run warms it; `--cold N` also times N runs, each from an empty
cache directory, and reports their medians and ranges (first runs swing ±15 % on a 2-core VM);
the many-seed run compiles its own program in a cache directory of its own, cold unless
`--warm-many`). From each run directory's summary.json: the seconds from process start and of
training until the delivered policy was solved (`solved_process_s`, `solved_wall_s`), and its
confirmed return; then the delivered policy of every seed is judged over `--episodes` episodes:
in Gymnasium where the task has a Gymnasium twin (`scripts/evaluate.py`'s `gymnasium_returns`;
InvertedPendulum-v5 for `fast`), else in the task itself from initial states no training
evaluation drew (`fresh_returns`; a Playground task through `envs.make`, whose adapter steps
the task's own physics, tests/test_playground.py). Writes benchmarks/results/delivered.json
(delivered-h100.json on an H100, delivered-NAME.json for `--preset NAME`; `--name` to choose;
command, machine, versions, date, every figure).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from benchmarks.provenance import machine_kind, provenance, write_result

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


class TrainFailed(SystemExit):
    """scripts/train.py exited non-zero: the command and the end of its stderr (`stderr`)."""

    def __init__(self, argv: list, stderr: str):
        super().__init__(f"{' '.join(argv)} failed:\n{stderr[-2000:]}")
        self.stderr = stderr


def train(out: str, *flags: str, cache_dir: str = None, env: dict = None) -> dict:
    """Runs the README's command into `out` (in `env`, default this process's environment); its
    summary.json with the process's wall time. `TrainFailed` if the command fails."""
    argv = [sys.executable, os.path.join(ROOT, "scripts", "train.py"), "--out", out, *flags]
    if cache_dir:
        argv += ["--cache-dir", cache_dir]
    start = time.perf_counter()
    proc = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - start
    if proc.returncode:
        raise TrainFailed(argv, proc.stderr)
    with open(os.path.join(out, "summary.json")) as f:
        return dict(json.load(f), process_wall_s=round(wall, 3))


def gymnasium_scores(run: str, seeds: int, episodes: int, first: int = 0) -> list:
    """Mean return over `episodes` episodes of each seed's delivered policy in the Gymnasium
    twin of the run's task; seed s of the run is judged on the episodes of seed `first` + s,
    so that runs of different seeds are judged on different episodes."""
    import gymnasium

    import envs
    import sac_jax
    from scripts.evaluate import gymnasium_returns

    policies = [sac_jax.load_policy(run, s) for s in range(seeds)]
    env = gymnasium.make(envs.spec(policies[0].config.env).gymnasium_id)
    try:
        return [float(np.mean(gymnasium_returns(policy, env, episodes, seed=1000 + first + s)))
                for s, policy in enumerate(policies)]
    finally:
        env.close()


def our_scores(run: str, seeds: int, episodes: int, first: int = 0) -> list:
    """Mean return over `episodes` episodes of the run's task as `envs.make` gives it (our
    InvertedPendulum-v5 steps as Gymnasium's does, tests/test_envs.py) of each seed's delivered
    policy, all seeds in one jitted evaluation, from initial states no training evaluation drew
    (`fresh_returns`; seed s of the run on the episodes of seed `first` + s)."""
    import sac_jax
    from benchmarks.fresh_episodes import fresh_returns
    from sac_jax import run_checkpoint

    config = sac_jax.load_policy(run, 0).config
    _, _, runner, _ = run_checkpoint.load_checkpoint(run)
    return fresh_returns(config, runner.delivered.actor_params, episodes, first)


def scorer(judge: str):
    """Where delivered policies are judged: "gymnasium", the task's twin there, or "ours", the
    task itself."""
    return gymnasium_scores if judge == "gymnasium" else our_scores


def main() -> None:
    import envs
    from sac_jax.presets import DEFAULT_PRESET, PRESETS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", choices=sorted(PRESETS), default=DEFAULT_PRESET,
                        help="the preset every run trains (default: the README's, %(default)s)")
    parser.add_argument("--seeds", type=int, nargs="+", default=list(range(10)))
    parser.add_argument("--many", type=int, default=32, help="seeds of the one many-seed run")
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--cold", type=int, nargs="?", const=1, default=0, metavar="N",
                        help="also N runs (default 1), each from an empty cache")
    parser.add_argument("--warm-many", action="store_true",
                        help="run the many-seed run twice and report the second (warm cache)")
    parser.add_argument("--name", default=None, help="results file: benchmarks/results/NAME.json "
                        "(default delivered on a CPU, delivered-KIND elsewhere: delivered-h100; "
                        "delivered-PRESET(-KIND) for another preset)")
    parser.add_argument("--judge", choices=("gymnasium", "ours"), default=None,
                        help="where the many-seed run's delivered policies are judged (ours: "
                        "all seeds at once on the device, for hundreds of seeds; default: as "
                        "every other run's, in Gymnasium where the task has a twin there)")
    args = parser.parse_args()
    spec = envs.spec(PRESETS[args.preset].env)
    judge = "gymnasium" if spec.gymnasium_id else "ours"
    if args.judge == "gymnasium" != judge:
        parser.error(f"--judge gymnasium: {spec.name} has no Gymnasium twin")
    score = scorer(judge)
    score_key = "gymnasium_return" if judge == "gymnasium" else "fresh_return"
    solved = f"at_least_{spec.solved_return:g}"
    preset = () if args.preset == DEFAULT_PRESET else ("--preset", args.preset)
    root = tempfile.mkdtemp(prefix="delivered-")
    result = {"preset": args.preset, "judged_in": judge, "episodes": args.episodes,
              "solved_return": spec.solved_return, "runs": [], "many": None, "cold": None}
    train(os.path.join(root, "warmup"), *preset)  # the compilation cache holds the program now
    for seed in args.seeds:
        out = os.path.join(root, f"seed{seed}")
        summary = train(out, *preset, "--seed", str(seed))
        row = {"seed": seed, "solved_process_s": summary["solved_process_s"][0],
               "solved_wall_s": summary["solved_wall_s"][0],
               "solved_at_step": summary["solved_at_step"][0],
               "delivered_return": summary["delivered_return"][0],
               "process_wall_s": summary["process_wall_s"],
               score_key: score(out, 1, args.episodes, seed)[0]}
        print(json.dumps(row), flush=True)
        result["runs"].append(row)
    if args.many:
        out = os.path.join(root, "many")
        many = (*preset, "--seeds", str(args.many), "--seed", "777")
        cache = tempfile.mkdtemp(prefix="cache-many-", dir=root)  # no earlier process's programs
        if args.warm_many:  # a first run compiles the many-seed program into the cache
            train(os.path.join(root, "many-warmup"), *many, cache_dir=cache)
        summary = train(out, *many, cache_dir=cache)
        many_judge = args.judge or judge
        scores = scorer(many_judge)(out, args.many, args.episodes)
        result["many"] = {"seeds": args.many, "seed": 777, "judged_in": many_judge,
                          "cache": "warm" if args.warm_many else "cold",
                          "all_solved_process_s": summary["all_solved_process_s"],
                          "all_solved_wall_s": summary["all_solved_wall_s"],
                          "solved": sum(s is not None for s in summary["solved_at_step"]),
                          "process_wall_s": summary["process_wall_s"],
                          "delivered_return": summary["delivered_return"],
                          "return": scores,
                          solved: sum(s >= spec.solved_return for s in scores)}
        print(json.dumps(result["many"]), flush=True)
    if args.cold:
        colds = []
        for i in range(args.cold):
            out = os.path.join(root, f"cold{i}")
            summary = train(out, *preset, cache_dir=tempfile.mkdtemp(prefix="cache-", dir=root))
            colds.append({"solved_process_s": summary["solved_process_s"][0],
                          "compile_s": summary["compile_s"],
                          "process_wall_s": summary["process_wall_s"],
                          score_key: score(out, 1, args.episodes)[0]})
            print(json.dumps(colds[-1]), flush=True)
        median = lambda key: float(np.median([np.inf if c[key] is None else c[key]
                                              for c in colds]))
        result["cold"] = {"solved_process_s": median("solved_process_s"),
                          "compile_s": median("compile_s"),
                          "process_wall_s": median("process_wall_s"),
                          score_key: min(c[score_key] for c in colds),
                          "runs": colds}
    runs = result["runs"]
    if runs:  # an unsolved run counts as never solved
        times = [np.inf if r["solved_process_s"] is None else r["solved_process_s"] for r in runs]
        result["warm"] = {
            "median_solved_process_s": float(np.median(times)),
            "max_solved_process_s": float(np.max(times)),
            f"{judge}_{solved}": sum(r[score_key] >= spec.solved_return for r in runs),
            "seeds": len(runs)}
    kind = machine_kind()
    name = "delivered" + ("" if args.preset == DEFAULT_PRESET else f"-{args.preset}")
    write_result(args.name or (name if kind == "cpu" else f"{name}-{kind}"), result,
                 provenance())


if __name__ == "__main__":
    main()
