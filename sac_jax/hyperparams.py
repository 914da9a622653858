"""`Hyperparams`: the numbers of a SAC run that change no shape, as a pytree.

A run reads them from its `SACConfig`, as constants of its compiled program. Given as arrays
instead, they are inputs of that program, so one program trains any of their values, and
`jax.vmap` over them trains many settings at once (`scripts/sweep.py`):

    config = sac_jax.PRESETS["fast"]
    train = jax.jit(jax.vmap(sac_jax.make_train(config, seed_axis="runs"), axis_name="runs"))
    settings = sac_jax.hyperparams.stack(
        [config.replace(actor_lr=lr, critic_lr=lr) for lr in (1e-3, 3e-3)])
    keys = jax.random.split(jax.random.key(0), 2)
    runner, metrics = train(keys, settings)   # setting i trained with key i

`settings` is a dict {name: array} of the hyperparameters that vary (here actor_lr and
critic_lr, each (2,)); one setting's is the same dict of scalars. `NAMES` are the fields that
may vary so: the discount and Polyak coefficients, the reward scale and loss factor, the
temperature's start and target, and the four Adam learning rates. Every other field (sizes,
counts, network shapes, choices) shapes the program: one program per value.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

import flax.struct
import jax
import jax.numpy as jnp

from sac_jax.config import SACConfig


class Hyperparams(flax.struct.PyTreeNode):
    """The values an agent's updates read (`Agent.hyperparams`): Python floats from its config,
    some replaced by traced scalars in an agent of `Agent.with_hyperparams`.

    gamma, tau, reward_scale, loss_coef: as `SACConfig`'s fields. alpha_init: alpha until the
    first temperature step; log_alpha_init: log alpha's start (`SACConfig.log_alpha_init`, or
    log(alpha_init)); target_entropy: H-bar of J_alpha (`SACConfig.target_entropy`, or -|A|);
    actor_lr, critic_lr, alpha_lr, value_lr: the Adam learning rates."""

    gamma: Any
    tau: Any
    reward_scale: Any
    loss_coef: Any
    alpha_init: Any
    log_alpha_init: Any
    target_entropy: Any
    actor_lr: Any
    critic_lr: Any
    alpha_lr: Any
    value_lr: Any


NAMES = tuple(Hyperparams.__dataclass_fields__)
"""The SACConfig fields a setting may vary within one compiled program."""


def of_config(config: SACConfig, action_size: int) -> Hyperparams:
    """`config`'s values as Python floats, its None defaults resolved for `action_size` actions."""
    values = {name: getattr(config, name) for name in NAMES}
    if values["log_alpha_init"] is None:
        values["log_alpha_init"] = math.log(config.alpha_init)
    if values["target_entropy"] is None:
        values["target_entropy"] = -float(action_size)
    return Hyperparams(**{name: float(v) for name, v in values.items()})


def stack(configs: Sequence[SACConfig]) -> Dict[str, jax.Array]:
    """The settings of `configs`, which must differ in `NAMES` only, as what
    `make_train(configs[0])`'s `train(key, hyperparams)` takes under `jax.vmap`: for each of
    `NAMES` whose (resolved) values differ between the configs, an array (n,), setting i
    from configs[i]. The others stay constants of the program, as in a run of one config, so a
    setting trains exactly as a run of its config would (a traced value is rounded alike, but
    XLA folds a constant: reward_scale 1.0 traced differs from the run's by float32 rounding)."""
    if not configs:
        raise ValueError("stack: no configs")
    base = configs[0]
    for i, config in enumerate(configs[1:], 1):
        for field in dataclasses.fields(base):
            name, value = field.name, getattr(config, field.name)
            if name not in NAMES and value != getattr(base, name):
                raise ValueError(f"stack: configs[{i}].{name}={value!r} differs from "
                                 f"configs[0]'s {getattr(base, name)!r}; one program trains "
                                 f"settings that differ only in {', '.join(NAMES)}")
    action_size = base.make_env().action_size
    each = [of_config(config, action_size) for config in configs]
    return {name: jnp.asarray(values)  # JAX's default float: float32 (float64 with x64)
            for name in NAMES
            if len(set(values := [getattr(h, name) for h in each])) > 1}


def run_index(setting: int, seed: int, seeds: int) -> int:
    """The run that trains seed `seed` (of `seeds`) of setting `setting` in a program of a
    sweep: runs are setting-major, each setting's seeds together."""
    return setting * seeds + seed


def setting_of(run: int, seeds: int) -> int:
    """The setting that run `run` of a sweep's program trains (`run_index`'s inverse)."""
    return run // seeds


def sweep(config: SACConfig, settings: Optional[Mapping[str, Sequence[float]]], seeds: int
          ) -> Tuple[List[SACConfig], Dict[str, jax.Array]]:
    """(configs, values) of a sweep of S settings x `seeds` seeds: configs[i] is `config` with
    setting i's values {name: values[i]} applied (validated); values, the `stack` of S x seeds
    runs, setting-major (run r trains configs[setting_of(r, seeds)]). ([config], {}) for no
    settings. ValueError naming a bad name, a bad value or unequal lengths."""
    if not settings:
        return [config], {}
    unknown = sorted(set(settings) - set(NAMES))
    if unknown:
        raise ValueError(f"settings: {unknown[0]} is not a hyperparameter one program can "
                         f"vary; those are {list(NAMES)}")
    for name, values in settings.items():
        if isinstance(values, (str, bytes)) or not isinstance(values, Sequence):
            raise ValueError(f"settings: {name}={values!r}: expected a list of values")
    lengths = {name: len(values) for name, values in settings.items()}
    if min(lengths.values()) < 1 or len(set(lengths.values())) > 1:
        raise ValueError("settings: every hyperparameter needs the same number (>= 1) of "
                         f"values, got {lengths}")
    configs = [config.replace(**{name: values[i] for name, values in settings.items()})
               for i in range(next(iter(lengths.values())))]
    return configs, stack([configs[setting_of(r, seeds)] for r in range(len(configs) * seeds)])
