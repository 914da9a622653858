"""Does every preset deliver? Trains N seeds of each named configuration in one run each and
scores every seed's delivered policy over 10 episodes of Gymnasium's twin of the task (our
environment, from fresh initial states, where Gymnasium has no twin: the Bullet-style
pendulum of `v1`), against the task's solved return.

    python -m benchmarks.presets_delivered          # cleanrl, pendulum, v1, double-pendulum
    python -m benchmarks.presets_delivered --runs pendulum --seeds 2

Writes benchmarks/results/NAME.json (`--name`, default presets_delivered-KIND:
presets_delivered-h100; command, machine, versions, date, every seed's score).
"""

from __future__ import annotations

import argparse
import json
import time

import jax
import numpy as np

import envs
import sac_jax
from benchmarks.provenance import provenance, result_name, write_result
from sac_jax.run import run_training
from sac_jax.saved_policy import SavedPolicy
from sac_jax.train import agent_for
from scripts.evaluate import gymnasium_returns


def score(policy: SavedPolicy, episodes: int, seed: int) -> float:
    """Mean return over `episodes` episodes in Gymnasium's twin, else in ours."""
    env_name = policy.config.env
    gym_id = envs.spec(env_name).gymnasium_id
    if gym_id is not None:
        import gymnasium
        env = gymnasium.make(gym_id)
        try:
            return float(np.mean(gymnasium_returns(policy, env, episodes, seed)))
        finally:
            env.close()
    returns = sac_jax.evaluate(policy.agent, envs.make(env_name), policy.actor_params,
                               jax.random.key(seed), episodes)
    return float(np.mean(returns))


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
    sac_jax.enable_compilation_cache()
    results = {}
    for name in args.runs:
        config = sac_jax.PRESETS[name]
        start = time.perf_counter()
        result = run_training(config, seeds=args.seeds)
        agent, _ = agent_for(config)
        scores = [score(SavedPolicy(config, {}, s, agent, jax.tree_util.tree_map(
            lambda x: x[s], result.state.delivered.actor_params)), args.episodes, 1000 + s)
            for s in range(args.seeds)]
        threshold = envs.spec(config.env).solved_return
        results[name] = {
            "env": config.env,
            "judged_in": "gymnasium" if envs.spec(config.env).gymnasium_id else "ours",
            "threshold": threshold, "scores": scores,
            "solved": sum(s >= threshold for s in scores), "seeds": args.seeds,
            "delivered_return": result.summary["delivered_return"],
            "delivered_at_step": result.summary["delivered_at_step"],
            "last_eval_return": result.summary["eval_return"],
            "run_steps": config.run_steps, "confirm_episodes": config.confirm_episodes,
            "seconds": round(time.perf_counter() - start, 1)}
        print(json.dumps({name: results[name]}), flush=True)
    write_result(args.name or result_name("presets_delivered"), results, source)


if __name__ == "__main__":
    main()
