"""The trained policy of a run directory, as a plain function of numpy observations.

    policy = sac_jax.load_policy("runs/pendulum", seed=0)
    action = policy(obs)            # obs (O,) -> action (A,); obs (B, O) -> actions (B, A)

The action is the deterministic a = scale * tanh(mu(s)) + bias, in the environment's units
(within [action_low, action_high]), computed by one jitted `Agent.act` on the actor parameters
of seed `seed` of the checkpoint (the run's state is vmapped over its seeds).
"""

from __future__ import annotations

from typing import Any

import jax
import numpy as np

from sac_jax import run_dir
from sac_jax.agent import Agent
from sac_jax.config import SACConfig
from sac_jax.train import agent_for


class SavedPolicy:
    """Deterministic policy of one seed of a saved run; call it with numpy observations.

    Attributes: `config` (the run's SACConfig), `info` (preset, seeds, seed of run.json),
    `seed` (which of the run's seeds, 0..seeds-1), `agent` and `actor_params` (that seed's
    actor parameters, for use inside JAX, e.g. with `sac_jax.evaluate`).
    """

    def __init__(self, config: SACConfig, info: dict, seed: int, agent: Agent, actor_params: Any):
        self.config, self.info, self.seed = config, info, seed
        self.agent, self.actor_params = agent, actor_params
        self._act = jax.jit(agent.act)

    @property
    def observation_size(self) -> int:
        return self.agent.observation_size

    @property
    def action_size(self) -> int:
        return self.agent.action_size

    def __call__(self, obs) -> np.ndarray:
        """obs (O,) or (B, O), any real dtype -> float32 action (A,) or (B, A)."""
        obs = np.asarray(obs, np.float32)
        if obs.ndim not in (1, 2) or obs.shape[-1] != self.observation_size:
            raise ValueError(f"obs of shape {obs.shape}: expected ({self.observation_size},) "
                             f"or (batch, {self.observation_size}) for {self.config.env}")
        return np.asarray(self._act(self.actor_params, obs))


def load_policy(path: str, seed: int = 0) -> SavedPolicy:
    """The deterministic policy of seed `seed` (0..seeds-1) of the run directory `path`.

    Reads config.json, run.json and checkpoint.msgpack; nothing is compiled but the policy
    (the checkpoint is checked against `jax.eval_shape` of the training state). Raises
    `run_dir.RunDirError` or `checkpoint.CheckpointError` (ValueErrors with one-line messages)
    for a missing or unreadable run directory or checkpoint, and ValueError for a seed the run
    does not have.
    """
    config, info = run_dir.read_config(path)
    seeds = info["seeds"]
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < seeds:
        raise ValueError(f"seed={seed!r}: run {path} has seeds 0..{seeds - 1}")
    _, _, runner, _ = run_dir.load_checkpoint(path)
    agent, _ = agent_for(config)
    params = jax.device_put(jax.tree_util.tree_map(lambda x: x[int(seed)],
                                                   runner.sac.actor_params))
    return SavedPolicy(config, info, int(seed), agent, params)
