"""sac-jax: Soft Actor-Critic in JAX/Flax, whole training runs as one compiled `lax.scan`.

Public API: `SACConfig`, `PRESETS`, `make_agent`, `Agent`, `SACState`, the updates
(`update_critic`, `update_actor`, `update_temperature`, `update_value`, `polyak_update`,
`sac_update`, `sample_noise`) and the objectives they differentiate (`critic_objective`,
`actor_objective`, `value_objective`), the losses module, the replay buffer module, `evaluate`,
`make_train` and its replay of recorded random draws (`Draws`, `record_draws`, `replay`), the
hyperparameters it takes as arrays to train many settings in one program (`hyperparams`), and
`load_policy` (a run directory's trained policy as a numpy function).
"""

from sac_jax import hyperparams, losses, replay_buffer
from sac_jax.agent import Agent, SACState, make_agent
from sac_jax.compilation_cache import enable_compilation_cache
from sac_jax.config import SACConfig
from sac_jax.evaluation import evaluate
from sac_jax.presets import DEFAULT_PRESET, PRESETS
from sac_jax.replay_buffer import ReplayBuffer, Transition
from sac_jax.saved_policy import SavedPolicy, load_policy
from sac_jax.randomness import Draws
from sac_jax.train import METRIC_NAMES, RunnerState, make_train, record_draws, replay
from sac_jax.updates import (actor_objective, critic_objective, polyak_update, sac_update,
                             sample_noise, update_actor, update_critic, update_temperature,
                             update_value, value_objective)

__all__ = [
    "Agent", "DEFAULT_PRESET", "Draws", "METRIC_NAMES", "PRESETS", "ReplayBuffer", "RunnerState",
    "SACConfig", "SACState", "SavedPolicy", "Transition", "actor_objective", "critic_objective",
    "enable_compilation_cache", "evaluate", "hyperparams", "load_policy", "losses", "make_agent",
    "make_train", "polyak_update", "record_draws", "replay", "replay_buffer", "sac_update",
    "sample_noise", "update_actor", "update_critic", "update_temperature", "update_value",
    "value_objective",
]
