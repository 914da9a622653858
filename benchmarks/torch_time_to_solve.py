"""Time to solve Gymnasium's InvertedPendulum-v5 with the seed-002 PyTorch SAC loop, on CPU.

The loop of seed 002 (CleanRL-style SAC v2), with its networks and update taken from
`references/cleanrl_sac.py` and its hyperparameters from the `cleanrl` preset (batch 256,
256x256 networks, policy lr 3e-4, q lr 1e-3, policy delay 2, 5,000 random steps):

    for global_step in 0, 1, ...:
        a = uniform random action         if global_step < learning_starts
            actor sample (tanh-squashed)  otherwise
        step one Gymnasium env; store (s, a, r, s', terminated) in the replay buffer
        if global_step > learning_starts: one update on a uniform batch (`CleanRLSAC.update`)

Differences from the seed's notebook, none of which changes the algorithm: one plain
`gym.make` environment instead of a one-environment `SyncVectorEnv`, a numpy replay buffer
instead of stable-baselines3's (both sample indices uniformly; s' is the real final observation
of an episode, and truncation at 1000 steps bootstraps as the seed's `handle_timeout_termination
=False` buffer does), and the reference's per-update copies of gradients (kept for the
equivalence tests) switched off.

Every `eval_every` steps after `learning_starts` (the `fast` preset's 2,048 and its 5 episodes),
the mean action tanh(mu(s)) scale + bias is run for `eval_episodes` episodes on a separate
environment; the run stops at the first evaluation whose mean return reaches 950, or at
`--max-steps`. Printed as one JSON line: steps and wall seconds to solve (the loop's wall time
up to the end of the solving evaluation, evaluations included), environment steps/s (all steps
/ loop wall time, evaluations included, as benchmarks/brax_peer.py counts), updates/s (updates /
seconds spent in sampling and updating) and the evaluation seconds, and written to
benchmarks/results/NAME.json (`--name`, default torch_time_to_solve-cpu: the loop runs on the
CPU wherever it runs; command, machine, versions, date).

    python -m benchmarks.torch_time_to_solve                 # seed 0, all cores
    python -m benchmarks.torch_time_to_solve --seeds 3 --threads 2
    python -m benchmarks.torch_time_to_solve --quick         # tiny run: checks the script only
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time


import gymnasium as gym
import numpy as np
import torch

import envs
from sac_jax.presets import PRESETS
from benchmarks.provenance import provenance, write_result
from references import cleanrl_sac

ENV = "InvertedPendulum-v5"
QUICK = dict(learning_starts=300, eval_every=200, eval_episodes=1, max_steps=700)


def evaluate(sac, env, episodes, seed):
    """Mean undiscounted return of `episodes` episodes of the deterministic (mean) action."""
    zeros = torch.zeros(1, *env.action_space.shape)
    returns = []
    for i in range(episodes):
        obs, _ = env.reset(seed=seed + i)
        total, done = 0.0, False
        while not done:
            with torch.no_grad():
                x = torch.as_tensor(obs, dtype=torch.float32)[None]
                action = sac.actor.get_action(x, zeros)[2]
            obs, reward, terminated, truncated, _ = env.step(action[0].numpy())
            total += float(reward)
            done = terminated or truncated
        returns.append(total)
    return float(np.mean(returns))


def run(seed, hp, threshold):
    """One run of the loop; returns its figures (see the module docstring)."""
    env, eval_env = gym.make(ENV), gym.make(ENV)
    obs_size, act_size = env.observation_space.shape[0], env.action_space.shape[0]
    sac = cleanrl_sac.CleanRLSAC(obs_size, act_size, env.action_space.low,
                                 env.action_space.high, seed=seed, gamma=hp["gamma"],
                                 tau=hp["tau"], policy_lr=hp["policy_lr"], q_lr=hp["q_lr"],
                                 policy_frequency=hp["policy_frequency"])
    capacity = min(hp["buffer_size"], hp["max_steps"])
    buf = dict(obs=np.zeros((capacity, obs_size), np.float32),
               action=np.zeros((capacity, act_size), np.float32),
               reward=np.zeros(capacity, np.float32),
               next_obs=np.zeros((capacity, obs_size), np.float32),
               terminated=np.zeros(capacity, np.float32))
    rng = np.random.default_rng(seed)
    env.action_space.seed(seed)
    obs, _ = env.reset(seed=seed)
    batch, learning_starts = hp["batch_size"], hp["learning_starts"]
    evals, update_s, eval_s, updates, solved = [], 0.0, 0.0, 0, None
    start = time.perf_counter()
    for global_step in range(hp["max_steps"]):
        if global_step < learning_starts:
            action = env.action_space.sample()
        else:
            with torch.no_grad():
                x = torch.as_tensor(obs, dtype=torch.float32)[None]
                action = sac.get_action(x, torch.randn(1, act_size))[0][0].numpy()
        next_obs, reward, terminated, truncated, _ = env.step(action)
        i = global_step % capacity
        buf["obs"][i], buf["action"][i], buf["reward"][i] = obs, action, reward
        buf["next_obs"][i], buf["terminated"][i] = next_obs, terminated
        obs = env.reset()[0] if terminated or truncated else next_obs

        if global_step > learning_starts:
            t = time.perf_counter()
            idx = rng.integers(0, min(global_step + 1, capacity), batch)
            data = cleanrl_sac.make_batch(*(buf[k][idx] for k in (
                "obs", "action", "reward", "next_obs", "terminated")))
            noise = {"critic": torch.randn(batch, act_size),
                     "actor": [torch.randn(batch, act_size)
                               for _ in range(hp["policy_frequency"])],
                     "temperature": [torch.randn(batch, act_size)
                                     for _ in range(hp["policy_frequency"])]}
            sac.update(data, noise, global_step)
            update_s += time.perf_counter() - t
            updates += 1

        steps = global_step + 1
        if steps > learning_starts and (steps - learning_starts) % hp["eval_every"] == 0:
            t = time.perf_counter()
            mean_return = evaluate(sac, eval_env, hp["eval_episodes"], 10_000 * (seed + 1) + steps)
            eval_s += time.perf_counter() - t
            evals.append((steps, round(mean_return, 1)))
            if mean_return >= threshold:
                solved = (steps, time.perf_counter() - start)
                break
    wall = time.perf_counter() - start
    return dict(seed=seed, steps=steps, wall_s=round(wall, 2), eval_s=round(eval_s, 2),
                evals=evals, solved_at_step=solved[0] if solved else None,
                solve_wall_s=round(solved[1], 2) if solved else None,
                env_steps_per_s=round(steps / wall, 1),
                updates_per_s=round(updates / update_s, 1) if updates else None)


def main():
    cleanrl, fast = PRESETS["cleanrl"], PRESETS["fast"]
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--threads", type=int, default=os.cpu_count(),
                        help="torch.set_num_threads (default: all cores)")
    parser.add_argument("--seeds", type=int, default=1, help="seeds 0..N-1, one run each")
    parser.add_argument("--max-steps", type=int, default=cleanrl.total_steps,
                        help="step budget of a run (default: the seed's 30,000)")
    parser.add_argument("--eval-every", type=int, default=fast.eval_every)
    parser.add_argument("--eval-episodes", type=int, default=fast.eval_episodes)
    parser.add_argument("--quick", action="store_true",
                        help=f"tiny run {QUICK} to check the script (figures meaningless)")
    parser.add_argument("--name", default=None, help="results file benchmarks/results/NAME.json "
                        "(default torch_time_to_solve-cpu)")
    args = parser.parse_args()
    for name in ("threads", "seeds", "max_steps", "eval_every", "eval_episodes"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")

    hp = dict(learning_starts=cleanrl.learning_starts, batch_size=cleanrl.batch_size,
              buffer_size=cleanrl.buffer_size, gamma=cleanrl.gamma, tau=cleanrl.tau,
              policy_lr=cleanrl.actor_lr, q_lr=cleanrl.critic_lr,
              policy_frequency=cleanrl.policy_frequency, max_steps=args.max_steps,
              eval_every=args.eval_every, eval_episodes=args.eval_episodes)
    if args.quick:
        hp.update(QUICK)
    if hp["learning_starts"] < hp["batch_size"]:
        parser.error(f"learning_starts={hp['learning_starts']} must be >= batch_size")
    torch.set_num_threads(args.threads)
    # The reference copies every gradient for the equivalence tests; the seed's loop does not.
    cleanrl_sac.grads = lambda layers: None
    threshold = envs.spec(ENV).solved_return

    runs = []
    for seed in range(args.seeds):
        runs.append(run(seed, hp, threshold))
        print(f"seed {seed}: {runs[-1]}", file=sys.stderr, flush=True)

    def median(key):
        values = [r[key] for r in runs]
        return None if None in values else statistics.median(values)

    keys = ("solved_at_step", "solve_wall_s", "env_steps_per_s", "updates_per_s")
    result = dict(
        benchmark="torch_time_to_solve", env=ENV, quick=args.quick, solved_return=threshold,
        hyperparameters=hp, threads=torch.get_num_threads(), torch=torch.__version__,
        gymnasium=gym.__version__, machine=platform.machine(), cpus=os.cpu_count(),
        median={k: median(k) for k in keys}, runs=runs)
    print(json.dumps(result))
    write_result(args.name or "torch_time_to_solve-cpu", result, provenance())


if __name__ == "__main__":
    main()
