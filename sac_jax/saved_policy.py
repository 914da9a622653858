"""The trained policy of a run directory, as a plain function of numpy observations.

    policy = sac_jax.load_policy("runs/pendulum", seed=0)                # the delivered policy
    policy = sac_jax.load_policy("runs/pendulum", seed=0, which="last")  # the last update's
    action = policy(obs)            # obs (O,) -> action (A,); obs (B, O) -> actions (B, A)

The action is the deterministic a = scale * tanh(mu(s)) + bias, in the environment's units
(within [action_low, action_high]), computed by one jitted `Agent.act` on the actor parameters
of seed `seed` of the checkpoint (the run's state is vmapped over its seeds): by default the
delivered actor, the one the run kept (`sac_jax.selection`).
"""

from __future__ import annotations

import warnings
from typing import Any, Literal

import jax
import numpy as np

from sac_jax import hyperparams, run_checkpoint, run_dir
from sac_jax.agent import Agent
from sac_jax.config import SACConfig
from sac_jax.train import agent_for


class SavedPolicy:
    """Deterministic policy of one seed of a saved run; call it with numpy observations.

    Attributes: `config` (the run's SACConfig), `info` (its `run_dir.RunInfo`),
    `seed` (which of the run's seeds, 0..seeds-1), `which` ("best": the delivered actor,
    "last": the last update's), `agent` and `actor_params` (that actor's parameters, for use
    inside JAX, e.g. with `sac_jax.evaluate`).
    """

    def __init__(self, config: SACConfig, info: dict, seed: int, agent: Agent, actor_params: Any,
                 which: str = "best"):
        self.config, self.info, self.seed, self.which = config, info, seed, which
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


def load_policy(path: str, seed: int = 0, which: Literal["best", "last"] = "best"
                ) -> SavedPolicy:
    """The deterministic policy of seed `seed` (0..seeds-1; in a sweep's run directory, run
    `seed` of the settings x seeds, setting-major) of the run directory `path`:
    `which="best"` the delivered actor (`sac_jax.selection`), `"last"` the last update's.

    Reads config.json, run.json and the newest checkpoint; nothing is compiled but the policy
    (the checkpoint is checked against `jax.eval_shape` of the training state). A run written
    by an earlier sac-jax kept no delivered actor: its last actor is loaded, with a warning
    saying so. Raises `run_dir.RunDirError` or `checkpoint.CheckpointError` (ValueErrors with
    one-line messages) for a missing or unreadable run directory or checkpoint, and ValueError
    for a seed the run does not have or another `which`.
    """
    if which not in ("best", "last"):
        raise ValueError(f"which={which!r}: must be 'best' or 'last'")
    config, info = run_dir.read_config(path)
    runs = info.runs  # seeds, times the settings of a sweep
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < runs:
        raise ValueError(f"seed={seed!r}: run {path} has seeds 0..{runs - 1}")
    _, _, runner, _ = run_checkpoint.load_checkpoint(path, earlier=True)
    if runner.delivered is None and which == "best":
        warnings.warn(f"{path} was written by an earlier sac-jax, which kept no delivered "
                      "policy: loading its last policy", stacklevel=2)
        which = "last"
    params = runner.delivered.actor_params if which == "best" else runner.sac.actor_params
    # a sweep's run: its setting's config (`sac_jax.hyperparams.sweep`, setting-major)
    config = hyperparams.sweep(config, info.settings, 1)[0][hyperparams.setting_of(
        int(seed), info.seeds)]
    agent, _ = agent_for(config)
    params = jax.device_put(jax.tree_util.tree_map(lambda x: x[int(seed)], params))
    return SavedPolicy(config, info, int(seed), agent, params, which)
