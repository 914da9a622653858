"""Evaluate a saved policy in our JAX environment and in Gymnasium's.

    python scripts/evaluate.py runs/pendulum                      # 10 episodes in each
    python scripts/evaluate.py runs/pendulum --episodes 50 --which gymnasium
    python scripts/evaluate.py runs/pendulum --paired --json      # same initial states

Runs the deterministic policy a = scale * tanh(mu(s)) + bias of one of the run's seeds, loaded
by `sac_jax.load_policy` (the delivered actor, or with `--policy last` the last update's), for
N episodes and prints the undiscounted return, mean ± std over the episodes, of each
environment:
    ours       `envs.make(env)`, the N episodes in parallel in one jitted `sac_jax.evaluate`
    gymnasium  `gymnasium.make(env)` (InvertedPendulum-v5/-v4, InvertedDoublePendulum-v5,
               Pendulum-v1), stepped on the host one action at a time

Ours draws its initial states from `--episode-seed`; Gymnasium resets with `seed=--episode-seed`
(its own sampler, so the episodes differ). With `--paired` each Gymnasium episode instead starts
from the initial state of the same episode of ours (MuJoCo's `set_state(qpos, qvel)`,
Pendulum's `state`), so the returns are compared episode by episode.

Gymnasium is an optional (test) dependency: pip install "gymnasium[mujoco]".
Bad input (run directory, checkpoint, seed, values) ends with one line on stderr and exit 2; a
missing dependency with one line and exit 1. Nothing is written.
"""

from __future__ import annotations

import dataclasses
import json
import warnings
from typing import Literal, Optional

import numpy as np
import tyro

import jax

import envs
import sac_jax
from envs.pendulum import PendulumData
from sac_jax import run_dir
from sac_jax.evaluation import initial_states
from sac_jax.messages import first_line
from sac_jax.cli import MissingDependency, fail, parse, positive, prng_seed, run_main

GYMNASIUM_MISSING = 'Gymnasium is not installed: pip install "gymnasium[mujoco]"'


@dataclasses.dataclass(frozen=True)
class EvaluateArgs:
    """Evaluate a saved policy in our JAX environment and in Gymnasium's."""

    run: tyro.conf.Positional[str]
    """Run directory written by scripts/train.py."""
    episodes: int = 10
    """Episodes in each environment."""
    seed: int = 0
    """Which of the run's seeds to evaluate, 0..seeds-1."""
    episode_seed: int = 0
    """PRNG seed of the episodes' initial states."""
    policy: Literal["best", "last"] = "best"
    """Which actor of the seed: "best", the delivered one (`sac_jax.selection`), or
    "last", the last update's."""
    which: Optional[Literal["ours", "gymnasium", "both"]] = None
    """Environments to evaluate in (default: both where Gymnasium has the task, else ours)."""
    paired: bool = False
    """Start Gymnasium's episodes from ours' initial states (needs --which both)."""
    json: bool = False
    """Print one JSON object (returns of every episode) instead of text."""

    def __post_init__(self):
        positive("episodes", self.episodes)
        prng_seed("episode_seed", self.episode_seed)
        if self.paired and self.which not in (None, "both"):
            raise ValueError(f"--paired compares ours with Gymnasium: needs --which both, "
                             f"not {self.which}")


def our_returns(policy: sac_jax.SavedPolicy, env, episodes: int, key: jax.Array) -> np.ndarray:
    """Returns (episodes,) of `sac_jax.evaluate` in our environment, started from
    `initial_states(env, jax.random.split(key, episodes))`."""
    run = jax.jit(lambda params, key: sac_jax.evaluate(policy.agent, env, params, key, episodes))
    return np.asarray(run(policy.actor_params, key), np.float64)


def _start_from(unwrapped, data):
    """Puts a Gymnasium environment (unwrapped, right after reset) into the physics state
    `data` of one of our environments; returns its observation there."""
    if isinstance(data, PendulumData):
        unwrapped.state = np.array([data.theta, data.theta_dot], np.float64)
    else:  # MJX: qpos (nq,), qvel (nv,); set_state runs mj_forward, as our reset does
        unwrapped.set_state(np.asarray(data.qpos, np.float64), np.asarray(data.qvel, np.float64))
    return unwrapped._get_obs()


def gymnasium_returns(policy, gym_env, episodes: int, seed: int, starts=None) -> np.ndarray:
    """Returns (episodes,) of `policy` in the Gymnasium environment `gym_env`, reset with
    `seed` before the first episode; `starts`: per episode, a physics state of ours to start
    from (`_start_from`), or None for Gymnasium's own initial states."""
    returns = np.zeros(episodes)
    for i in range(episodes):
        obs, _ = gym_env.reset(seed=seed if i == 0 else None)
        if starts is not None:
            obs = _start_from(gym_env.unwrapped, jax.tree_util.tree_map(lambda x: x[i], starts))
        done = False
        while not done:
            obs, reward, terminated, truncated, _ = gym_env.step(policy(obs))
            returns[i] += float(reward)
            done = terminated or truncated
    return returns


def _gymnasium_id(env_name: str) -> str:
    gym_id = envs.spec(env_name).gymnasium_id
    if gym_id is None:
        covered = [name for name in envs.registered() if envs.spec(name).gymnasium_id]
        raise ValueError(f"{env_name} has no Gymnasium counterpart (Gymnasium evaluation covers "
                         f"{', '.join(covered)}); use --which ours")
    return gym_id


def _make_gymnasium(gym_id: str):
    """`gymnasium.make(gym_id)`; MissingDependency (one line) if Gymnasium or what the
    environment needs is not installed."""
    try:
        import gymnasium
    except ImportError:
        raise MissingDependency(GYMNASIUM_MISSING) from None
    try:
        with warnings.catch_warnings():  # e.g. "InvertedPendulum-v4 is out of date": asked for
            warnings.simplefilter("ignore", DeprecationWarning)
            return gymnasium.make(gym_id)
    except gymnasium.error.DependencyNotInstalled as error:  # e.g. no mujoco for MuJoCo envs
        raise MissingDependency(f"{first_line(error)}; "
                                f"{GYMNASIUM_MISSING}") from None


def _summary(returns: np.ndarray) -> dict:
    return {"mean": float(returns.mean()), "std": float(returns.std()),
            "returns": [float(r) for r in returns]}


def main(argv=None) -> int:
    try:
        args = parse(EvaluateArgs, argv, description=__doc__)
        config, _ = run_dir.read_config(args.run)
        twin = envs.spec(config.env).gymnasium_id is not None
        which = args.which or ("both" if twin or args.paired else "ours")
        use_ours, use_gym = which in ("ours", "both"), which in ("gymnasium", "both")
        gym_id = _gymnasium_id(config.env) if use_gym else None
        sac_jax.enable_compilation_cache()
        policy = sac_jax.load_policy(args.run, args.seed, args.policy)
    except ValueError as error:  # also UsageError, RunDirError and CheckpointError
        return fail(error, 2)
    try:  # before anything is compiled
        gym_env = _make_gymnasium(gym_id) if use_gym else None
    except MissingDependency as error:
        return fail(error, 1)

    results = {"run": args.run, "env": config.env, "seed": args.seed, "policy": policy.which,
               "episode_seed": args.episode_seed, "episodes": args.episodes}
    key = jax.random.key(args.episode_seed)
    env = config.make_env()
    try:
        if use_ours:
            results["ours"] = _summary(our_returns(policy, env, args.episodes, key))
        if use_gym:
            starts = (jax.device_get(initial_states(env, jax.random.split(key, args.episodes)).data)
                      if args.paired else None)
            results["gymnasium"] = _summary(
                gymnasium_returns(policy, gym_env, args.episodes, args.episode_seed, starts))
    finally:
        if gym_env is not None:
            gym_env.close()
    if args.paired:
        difference = np.subtract(results["ours"]["returns"], results["gymnasium"]["returns"])
        results["max_abs_difference"] = float(np.max(np.abs(difference)))

    if args.json:
        print(json.dumps(results))
        return 0
    name = {"best": "delivered"}.get(policy.which, policy.which)  # "best" names the delivered
    print(f"{config.env}, seed {args.seed} of {args.run}, {name} policy:")
    for name in ("ours", "gymnasium"):
        if name in results:
            r = results[name]
            print(f"{name}: {r['mean']:.1f} ± {r['std']:.1f} over {args.episodes} episodes")
    if args.paired:
        print(f"paired: max |ours - gymnasium| = {results['max_abs_difference']:.3g} per episode")
    return 0


if __name__ == "__main__":
    run_main(main)
