"""The delivered policy: each seed keeps, inside the compiled loop, the actor with the best
confirmed evaluation so far, and what a run hands over is that actor, not the last update's.

At every evaluation point the loop evaluates the current actor on `eval_episodes` episodes
(the score s). The kept actor has a confirmed score c* (-inf before the first point).

    candidate       s > c*
    confirmation    a candidate is evaluated again on `confirm_episodes` episodes from fresh
                    initial states (keys no other evaluation uses): the confirmed score c
    replacement     the candidate becomes the kept actor, with c* <- c, only if c > c*

The confirmed score is measured after the choice of candidate, on other episodes, so a lucky
evaluation (s high by chance) is never what the kept score records: to replace the kept actor,
a candidate must do better again on fresh initial states. A tie keeps the older actor, so a
task whose returns saturate (1000 of 1000 on the inverted pendulum) keeps the first actor that
reached the top.

With `SACConfig.stop_when_solved` a seed whose c* reaches `SACConfig.stop_at` (by default the
task's solved return) stops learning: its learner state and kept actor no longer change
(`sac_jax.train`), as Stable-Baselines3's StopTrainingOnRewardThreshold stops a run.
"""

from __future__ import annotations

from typing import Any, Tuple

import flax.struct
import jax
import jax.numpy as jnp


class Delivered(flax.struct.PyTreeNode):
    """The kept actor of one seed and how it was chosen.

    actor_params  parameters of the kept actor (those of the learner's actor at init)
    score         () float32, its confirmed evaluation return c* (-inf until the first point)
    env_steps     () int32, environment steps done when it was selected (-1 until then)
    """

    actor_params: Any
    score: jax.Array
    env_steps: jax.Array


def init(actor_params) -> Delivered:
    """Nothing selected yet: the initial actor, with score -inf."""
    return Delivered(actor_params=actor_params, score=jnp.float32(-jnp.inf),
                     env_steps=jnp.int32(-1))


def select(delivered: Delivered, actor_params, score: jax.Array, confirmed: jax.Array,
           env_steps: jax.Array) -> Tuple[Delivered, jax.Array]:
    """One selection step (see the module docstring): `score` is the current actor's
    evaluation return s, `confirmed` its return c on the fresh confirmation episodes (the
    training loop steps both sets of episodes as one batch, so c exists at every point; it
    counts for a candidate only). Returns (the kept actor after the step, c, or NaN where the
    actor was not a candidate)."""
    score = score.astype(jnp.float32)
    candidate = score > delivered.score
    confirmed = jnp.where(candidate, confirmed.astype(jnp.float32), jnp.float32(jnp.nan))
    better = candidate & (confirmed > delivered.score)
    chosen = Delivered(actor_params=actor_params, score=confirmed,
                       env_steps=jnp.asarray(env_steps, jnp.int32))
    kept = jax.tree_util.tree_map(lambda new, old: jnp.where(better, new, old), chosen, delivered)
    return kept, confirmed
