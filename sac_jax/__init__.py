"""sac-jax: Soft Actor-Critic in JAX/Flax, whole training runs as one compiled `lax.scan`.

Public API: `SACConfig`, `PRESETS`, `make_agent`, `Agent`, `SACState`, the updates
(`update_critic`, `update_actor`, `update_temperature`, `update_value`, `polyak_update`,
`sac_update`, `sample_noise`) and the objectives they differentiate (`critic_objective`,
`actor_objective`, `value_objective`), the losses module, the replay buffer module, `evaluate`,
`make_train` and its replay of recorded random draws (`Draws`, `record_draws`, `replay`), the
hyperparameters it takes as arrays to train many settings in one program (`hyperparams`), and
`load_policy` (a run directory's trained policy as a numpy function).

Each name is imported on first use (PEP 562's module `__getattr__`): `import sac_jax` imports
no JAX, so a process that needs none of it, such as the one writing a run's records
(`sac_jax.records_process`), runs `python -m sac_jax.<module>` without JAX's 1.3 s of imports.
"""

import importlib

_HOMES = {
    "hyperparams": None, "losses": None, "replay_buffer": None,
    "Agent": "agent", "SACState": "agent", "make_agent": "agent",
    "enable_compilation_cache": "compilation_cache",
    "SACConfig": "config",
    "evaluate": "evaluation",
    "DEFAULT_PRESET": "presets", "PRESETS": "presets",
    "ReplayBuffer": "replay_buffer", "Transition": "replay_buffer",
    "SavedPolicy": "saved_policy", "load_policy": "saved_policy",
    "Draws": "randomness",
    "METRIC_NAMES": "train", "RunnerState": "train", "make_train": "train",
    "record_draws": "train", "replay": "train",
    "actor_objective": "updates", "critic_objective": "updates", "polyak_update": "updates",
    "sac_update": "updates", "sample_noise": "updates", "update_actor": "updates",
    "update_critic": "updates", "update_temperature": "updates", "update_value": "updates",
    "value_objective": "updates",
}
"""Each public name and the module of this package that defines it (None: the name is a
module of its own)."""

__all__ = sorted(_HOMES)


def __getattr__(name: str):
    if name not in _HOMES:
        raise AttributeError(f"module 'sac_jax' has no attribute {name!r}")
    home = _HOMES[name]
    if home is None:
        return importlib.import_module(f"sac_jax.{name}")  # also sets the attribute
    value = getattr(importlib.import_module(f"sac_jax.{home}"), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
