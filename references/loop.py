"""Seed 002's training loop around the seed-002 agent (`cleanrl_sac.CleanRLSAC`), driven by a
recorded stream of random draws, for the whole-loop equivalence test.

The seed's loop, per vector step `global_step` (n environments at once):

    actions  uniform samples of the action space while global_step < learning_starts,
             else actor.get_action(obs)
    step     envs.step(actions) -> next_obs, rewards, terminations, truncations, infos
             (SyncVectorEnv; an ended copy restarts at once and next_obs is its reset obs)
    store    rb.add(obs, next_obs.copy(), actions, rewards, terminations, infos) into
             stable-baselines3's ReplayBuffer(n_envs=n, handle_timeout_termination=False)
    obs = next_obs
    learn    data = rb.sample(batch_size); the update block (`CleanRLSAC.update`)

Changes, each to match sac_jax's loop (docs/equivalence.md lists them with the seed's own
behaviour):
* every draw comes from the stream: the uniform actions (`action_space.sample()`), the
  policy's noise eps, the minibatch slots (`rb.sample`) and the update noise;
* updates run from global_step >= learning_starts (the seed: >), updates_per_step of them per
  vector step (the seed: 1), and the k-th update gets the global_step learning_starts + k,
  which is the seed's own global_step for its k-th update when there is one per step (the
  policy delay `global_step % policy_frequency == 0` then falls on the same updates);
* real_next_obs instead of next_obs: a copy truncated by the time limit stores its final
  observation, not its reset one (CleanRL's `infos["final_observation"]` fix, which the seed
  dropped).

`ReplayBuffer` is written after stable-baselines3's (its storage layout and dtypes);
`JaxVectorEnv` presents one of our JAX environments to this loop as the black box
SyncVectorEnv is to the seed (the environments are tested against Gymnasium separately).
"""

from __future__ import annotations

from typing import Dict, Iterator

import jax
import numpy as np
import torch

import envs
from references.cleanrl_sac import CleanRLSAC, make_batch


class JaxVectorEnv:
    """n copies of a JAX environment behind Gymnasium 0.29's SyncVectorEnv interface (same-step
    auto-reset): `step` returns numpy arrays, and infos["final_observation"] holds the
    observation each ended copy reached (infos["_final_observation"] marks those copies)."""

    def __init__(self, vec: envs.VectorEnv, state: envs.VectorState):
        self._step = jax.jit(vec.step)
        self._state = state
        self.num_envs = vec.num_envs

    def reset(self) -> np.ndarray:
        """The current observations (n, O); the copies start from the state given."""
        return np.array(self._state.env_state.obs)

    def step(self, actions: np.ndarray):
        self._state, out = self._step(self._state, actions)
        out = jax.tree_util.tree_map(np.array, out)  # writable numpy copies
        infos = {"final_observation": out.final_obs, "_final_observation": out.done}
        return out.obs, out.reward, out.terminated, out.truncated, infos


class ReplayBuffer:
    """stable-baselines3's ReplayBuffer as the seed builds it (n_envs copies,
    handle_timeout_termination=False, optimize_memory_usage=False): float32 arrays of
    buffer_size // n_envs rows of n_envs transitions, row `pos` written by one `add` of a
    vector step, wrapping around. `sample_at(slots)` reads flat slots s = row * n_envs + env,
    the numbering of sac_jax's ring buffer, where SB3's `sample` would draw (row, env) pairs."""

    def __init__(self, buffer_size: int, obs_size: int, action_size: int, n_envs: int):
        self.rows, self.n_envs, self.pos, self.full = buffer_size // n_envs, n_envs, 0, False
        shape = lambda *rest: (self.rows, n_envs) + rest
        self.observations = np.zeros(shape(obs_size), np.float32)
        self.next_observations = np.zeros(shape(obs_size), np.float32)
        self.actions = np.zeros(shape(action_size), np.float32)
        self.rewards = np.zeros(shape(), np.float32)
        self.dones = np.zeros(shape(), np.float32)

    def add(self, obs, next_obs, action, reward, done) -> None:
        self.observations[self.pos] = np.array(obs)
        self.next_observations[self.pos] = np.array(next_obs)
        self.actions[self.pos] = np.array(action)
        self.rewards[self.pos] = np.array(reward)
        self.dones[self.pos] = np.array(done)
        self.pos += 1
        if self.pos == self.rows:
            self.full, self.pos = True, 0

    def size(self) -> int:
        return (self.rows if self.full else self.pos) * self.n_envs

    def sample_at(self, slots: np.ndarray, dtype=torch.float32):
        """The seed's batch (rewards, dones (B, 1)) of flat slots (B,), all in [0, size)."""
        slots = np.asarray(slots)
        if slots.min() < 0 or slots.max() >= self.size():
            raise ValueError(f"slots outside the {self.size()} filled ones: "
                             f"[{slots.min()}, {slots.max()}]")
        row, env = slots // self.n_envs, slots % self.n_envs
        return make_batch(self.observations[row, env], self.actions[row, env],
                          self.rewards[row, env], self.next_observations[row, env],
                          self.dones[row, env], dtype=dtype)


def train(agent: CleanRLSAC, envs_: JaxVectorEnv, rb: ReplayBuffer, draws: Dict[str, np.ndarray],
          learning_starts: int, dtype=torch.float32) -> Iterator[int]:
    """Runs the loop (see the module docstring) for as many vector steps as `draws` has, in
    place on `agent` and `rb`, yielding the number of updates done after each vector step (so
    a caller can look at the agent in between).

    draws: numpy arrays with a leading axis of vector steps T, as `sac_jax.record_draws`
    makes them: random_action (T, n, A), action_noise (T, n, A), batch_index (T, U, B),
    update_noise {"critic": (T, U, B, A), "actor", "temperature": (T, U, K, B, A)}.
    `learning_starts` counts vector steps, as the seed's global_step does.
    """
    t = lambda x: torch.as_tensor(np.asarray(x), dtype=dtype)
    updates = 0
    obs = envs_.reset()
    for global_step in range(len(draws["random_action"])):
        if global_step < learning_starts:
            actions = draws["random_action"][global_step]
        else:
            actions, _, _ = agent.actor.get_action(t(obs), t(draws["action_noise"][global_step]))
            actions = actions.detach().cpu().numpy()

        next_obs, rewards, terminations, truncations, infos = envs_.step(actions)

        real_next_obs = next_obs.copy()
        for idx, trunc in enumerate(truncations):
            if trunc:
                real_next_obs[idx] = infos["final_observation"][idx]
        rb.add(obs, real_next_obs, actions, rewards, terminations)

        obs = next_obs

        if global_step >= learning_starts:
            for u, slots in enumerate(draws["batch_index"][global_step]):
                data = rb.sample_at(slots, dtype)
                noise = {k: v[global_step, u] for k, v in draws["update_noise"].items()}
                updates += 1
                agent.update(data, {"critic": t(noise["critic"]),
                                    "actor": [t(x) for x in noise["actor"]],
                                    "temperature": [t(x) for x in noise["temperature"]]},
                             global_step=learning_starts + updates)
        yield updates
