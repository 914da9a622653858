"""Would storing each observation once shrink the replay buffer? Measured on real runs.

A slot holds (obs, action, reward, next_obs, terminated). Within an episode, a slot's next_obs
is the obs of the same environment's next slot (E slots on, E = num_envs), so storing it again
is redundant there; at an episode's end it is not: the environment resets, the next slot holds
the reset observation, and the true final observation (which a truncation bootstraps from) is
needed besides. Storing observations once while keeping every sampled transition identical
therefore needs a second store for the final observations of the episode ends in the buffer,
and in a fixed-shape (jit) buffer that store must hold as many as can occur: one per slot when
every step ends an episode, which saves nothing. A smaller store saves bytes only by dropping
or altering transitions once more episodes end than it holds.

This script trains each preset (1 seed, its own configuration) and counts, in the final replay
buffer, the slots whose next_obs differs from the next slot's obs (the episode ends), the
largest share of them among the transitions stored at any evaluation point being what a
second store sized by measurement would have to hold. Writes
benchmarks/results/observation_once-KIND.json (command, machine, versions, date).

    python -m benchmarks.observation_once                      # fast and double-pendulum
"""

from __future__ import annotations

import argparse
import json

import jax
import numpy as np

import sac_jax
from benchmarks.provenance import provenance, result_name, write_result
from sac_jax.run import run_training


def episode_ends(data, num_envs: int, filled: int) -> np.ndarray:
    """Whether each of the first `filled - num_envs` slots (in the order written: the runs here
    never wrap) ends an episode: its next_obs is not the obs of its environment's next slot."""
    obs, next_obs = np.asarray(data.obs[0, :filled]), np.asarray(data.next_obs[0, :filled])
    return np.any(next_obs[:-num_envs] != obs[num_envs:], axis=-1)


def measure(preset: str) -> dict:
    config = sac_jax.PRESETS[preset].replace(stop_when_solved=False)
    if config.total_steps > config.buffer_size:
        raise SystemExit(f"{preset}: the buffer wraps, the slot order is not the time order")
    state = run_training(config, seeds=1).state
    filled = int(np.asarray(state.buffer.size).ravel()[0])
    data = jax.device_get(state.buffer.data)
    ends = episode_ends(data, config.num_envs, filled)
    # the share of episode ends among the transitions stored at each evaluation point
    points = np.arange(config.eval_every, filled, config.eval_every)
    shares = [float(ends[:p].mean()) for p in points if p <= ends.size]
    obs_bytes = int(np.prod(data.obs.shape[2:])) * data.obs.dtype.itemsize
    slot = sum(int(np.prod(x.shape[2:])) * x.dtype.itemsize
               for x in jax.tree_util.tree_leaves(data))
    worst = max(shares)
    return {
        "env": config.env, "num_envs": config.num_envs, "slots_filled": filled,
        "slot_bytes": slot, "observation_bytes": obs_bytes,
        "episode_end_share_final": round(float(ends.mean()), 4),
        "episode_end_share_max": round(worst, 4),
        # obs once + a store of final observations for every slot (exact in every case): the
        # observation saved comes back in that store
        "slot_bytes_once_exact": slot,
        # obs once + a store sized to this run's largest share (+ a 4-byte slot index each)
        "slot_bytes_once_sized_to_this_run": round(slot - obs_bytes + worst * (obs_bytes + 4), 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", nargs="+", default=["fast", "double-pendulum"],
                        choices=sorted(sac_jax.PRESETS))
    args = parser.parse_args()
    source = provenance()
    sac_jax.enable_compilation_cache()
    result = {preset: measure(preset) for preset in args.presets}
    print(json.dumps(result))
    write_result(result_name("observation_once"), result, source)


if __name__ == "__main__":
    main()
