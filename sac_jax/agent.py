"""`Agent` (the static parts: config, networks, optimisers, action bounds, and the numeric
hyperparameters the updates read) and `SACState` (the pytree of everything that changes:
parameters, target parameters, optimiser states, temperature).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Mapping, Optional, Tuple

import flax.struct
import jax
import jax.numpy as jnp
import numpy as np
import optax

from sac_jax import observation_norm
from sac_jax.config import SACConfig
from sac_jax.hyperparams import Hyperparams, of_config
from sac_jax.networks import Actor, CriticEnsemble, ValueNetwork
from sac_jax.policy import deterministic_action, squashed_gaussian_sample


class SACState(flax.struct.PyTreeNode):
    """All mutable training state. Unused parts are None (critic targets in v1, value in v2).

    `alpha` is the temperature the losses use; it becomes exp(log_alpha) after each temperature
    step (before the first one it is `hyperparams.alpha_init`). `step` counts `sac_update` calls.
    """

    actor_params: Any
    critic_params: Any
    critic_target_params: Any
    value_params: Any
    value_target_params: Any
    actor_opt_state: Any
    critic_opt_state: Any
    value_opt_state: Any
    alpha_opt_state: Any
    log_alpha: jax.Array
    alpha: jax.Array
    step: jax.Array


def adam(learning_rate: float) -> optax.GradientTransformation:
    """Adam with PyTorch's defaults (betas 0.9, 0.999; eps 1e-8 added to sqrt(v-hat))."""
    return optax.adam(learning_rate, b1=0.9, b2=0.999, eps=1e-8)


@dataclasses.dataclass(frozen=True, eq=False)
class Agent:
    """Static description of a SAC learner; a pytree with no leaves, so it can be passed to
    jitted functions as an ordinary argument. Build it with `make_agent`.

    The updates read every number that shapes nothing (gamma, tau, learning rates, ...) from
    `hyperparams`: the config's constants, some of them traced values in an agent that
    `with_hyperparams` built inside a traced function (do not pass that one into a new
    `jax.jit`)."""

    config: SACConfig
    observation_size: int
    action_size: int
    action_low: Tuple[float, ...]
    action_high: Tuple[float, ...]
    actor: Actor
    critic: CriticEnsemble
    value: Optional[ValueNetwork]
    hyperparams: Hyperparams
    actor_optimizer: optax.GradientTransformation
    critic_optimizer: optax.GradientTransformation
    value_optimizer: optax.GradientTransformation
    alpha_optimizer: optax.GradientTransformation

    @property
    def action_scale(self) -> jax.Array:
        """(high - low) / 2, shape (A,)."""
        return (jnp.asarray(self.action_high) - jnp.asarray(self.action_low)) / 2.0

    @property
    def action_bias(self) -> jax.Array:
        """(high + low) / 2, shape (A,)."""
        return (jnp.asarray(self.action_high) + jnp.asarray(self.action_low)) / 2.0

    def with_hyperparams(self, values: Optional[Mapping[str, jax.Array]]) -> "Agent":
        """This agent with `values` {name: scalar} (traced values of one setting, names from
        `sac_jax.hyperparams.NAMES`) in place of its own, the optimisers rebuilt for their
        learning rates; itself for None or {}."""
        if not values:
            return self
        hyperparams = self.hyperparams.replace(**values)
        return dataclasses.replace(self, hyperparams=hyperparams, **_optimizers(hyperparams))

    # ------------------------------------------------------------------ policy
    def sample_action(self, actor_params, obs: jax.Array, noise: jax.Array):
        """a ~ pi(.|s) reparameterised by noise eps (B, A); returns (a (B, A), log pi (B,)).
        Observations are raw: normalised here with the actor's statistics, if it has them
        (`sac_jax.observation_norm`)."""
        mean, log_std = self.actor.apply(actor_params,
                                         observation_norm.normalize(actor_params, obs))
        return squashed_gaussian_sample(mean, log_std, noise, self.action_scale,
                                        self.action_bias, self.config.log_prob_correction)

    def act(self, actor_params, obs: jax.Array) -> jax.Array:
        """The deterministic action scale * tanh(mu(s)) + bias in environment units for obs
        (..., O) (raw observations, as `sample_action`); a sampled one is `sample_action`'s."""
        mean, _ = self.actor.apply(actor_params, observation_norm.normalize(actor_params, obs))
        return deterministic_action(mean, self.action_scale, self.action_bias)

    # ------------------------------------------------------------------ state
    def init(self, key: jax.Array) -> SACState:
        """Fresh parameters (targets as copies of the online networks) and optimiser states;
        with `normalize_observations`, the actor's variables also hold the observation
        statistics (`sac_jax.observation_norm`), before any observation."""
        k_actor, k_critic, k_value = jax.random.split(key, 3)
        obs = jnp.zeros((1, self.observation_size), jnp.float32)
        action = jnp.zeros((1, self.action_size), jnp.float32)
        actor_params = self.actor.init(k_actor, obs)
        if self.config.normalize_observations:
            actor_params = {**actor_params,
                            observation_norm.COLLECTION: observation_norm.init(obs.shape[-1])}
        critic_params = self.critic.init(k_critic, obs, action)
        v1 = self.config.variant == "v1"
        value_params = self.value.init(k_value, obs) if v1 else None
        log_alpha = jnp.asarray(self.hyperparams.log_alpha_init, jnp.float32)
        return SACState(
            actor_params=actor_params,
            critic_params=critic_params,
            critic_target_params=None if v1 else critic_params,
            value_params=value_params,
            value_target_params=value_params,
            actor_opt_state=self.actor_optimizer.init(actor_params),
            critic_opt_state=self.critic_optimizer.init(critic_params),
            value_opt_state=self.value_optimizer.init(value_params) if v1 else None,
            alpha_opt_state=self.alpha_optimizer.init(log_alpha),
            log_alpha=log_alpha,
            alpha=jnp.asarray(self.hyperparams.alpha_init, jnp.float32),
            step=jnp.int32(0),
        )


jax.tree_util.register_static(Agent)


def _optimizers(hyperparams: Hyperparams) -> dict:
    return {f"{name}_optimizer": adam(getattr(hyperparams, f"{name}_lr"))
            for name in ("actor", "critic", "value", "alpha")}


def make_agent(config: SACConfig, observation_size: int, action_size: int,
               action_low, action_high) -> Agent:
    """An `Agent` for observations of size O and actions of size A in [low, high] (each (A,))."""
    def bounds(name: str, values) -> tuple:
        values = np.asarray(values, np.float64)
        if values.size not in (1, action_size) or values.ndim > 1:
            raise ValueError(f"{name} has shape {values.shape}, expected a scalar or "
                             f"({action_size},) for action_size={action_size}")
        return tuple(float(x) for x in np.broadcast_to(values.ravel(), (action_size,)))

    low, high = bounds("action_low", action_low), bounds("action_high", action_high)
    if not all(math.isfinite(l) and math.isfinite(h) and l < h for l, h in zip(low, high)):
        raise ValueError(f"action bounds must be finite with low < high, got low={low}, "
                         f"high={high}")
    c = config
    hyperparams = of_config(c, action_size)
    hidden_dtype = jnp.bfloat16 if c.hidden_dtype == "bfloat16" else None
    return Agent(
        config=c,
        observation_size=int(observation_size),
        action_size=int(action_size),
        action_low=low,
        action_high=high,
        actor=Actor(action_size=action_size, hidden_sizes=c.actor_hidden, initializer=c.init,
                    last_layer_init=c.last_layer_init,
                    separate_log_std_network=c.separate_log_std_network,
                    log_std_mode=c.log_std_mode, log_std_min=c.log_std_min,
                    log_std_max=c.log_std_max, hidden_dtype=hidden_dtype),
        critic=CriticEnsemble(hidden_sizes=c.critic_hidden, num_critics=c.num_critics,
                              initializer=c.init, last_layer_init=c.last_layer_init,
                              hidden_dtype=hidden_dtype, layer_norm=c.critic_layer_norm),
        value=(ValueNetwork(hidden_sizes=c.critic_hidden, initializer=c.init,
                            last_layer_init=c.last_layer_init, hidden_dtype=hidden_dtype)
               if c.variant == "v1" else None),
        hyperparams=hyperparams,
        **_optimizers(hyperparams),
    )
