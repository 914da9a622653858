"""Each seed's delivered actor scored on episodes from initial states no training evaluation
drew: the check that a run's kept score (`sac_jax.selection`) is the policy it hands over."""

from __future__ import annotations

from typing import List

import jax
import jax.numpy as jnp

import sac_jax
from sac_jax.train import agent_for

FRESH_KEY = 20261125
"""The root of the fresh episodes' keys (seed s draws from `split(key(FRESH_KEY), n)[s]`, the
same for any n > s);
training draws its evaluations from `key(seed)`'s chain."""


def fresh_returns(config: sac_jax.SACConfig, actor_params, episodes: int,
                  first: int = 0) -> List[float]:
    """Mean return over `episodes` deterministic episodes of each seed's actor (`actor_params`
    with a leading axis of seeds, e.g. `run_training(...).state.delivered.actor_params`), all
    seeds in one jitted `sac_jax.evaluate`; seed s on the episodes of seed `first` + s."""
    agent, env = agent_for(config)
    seeds = jax.tree_util.tree_leaves(actor_params)[0].shape[0]
    evaluate = jax.jit(jax.vmap(lambda params, key: jnp.mean(
        sac_jax.evaluate(agent, env, params, key, episodes))))
    return [float(x) for x in evaluate(actor_params, jax.random.split(
        jax.random.key(FRESH_KEY), first + seeds)[first:])]
