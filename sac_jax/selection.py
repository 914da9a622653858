"""The delivered policy: each seed keeps, inside the compiled loop, the actor that has beaten
every candidate since on the same confirmation episodes, and what a run hands over is that
actor, not the last update's.

At every evaluation point the loop evaluates the current actor on `eval_episodes` episodes
(the score s), then on `confirm_episodes` episodes from fresh initial states (keys no other
evaluation uses, the confirmed return c), and the kept actor on those same confirmation
episodes (k). The kept actor has a kept score c* (-inf before the first point).

    candidate       s > c*
    replacement     a candidate becomes the kept actor, with c* <- c and n <- 1, only if
                    c > k: it beats the kept actor on the same initial states (at the first
                    point, where nothing is kept yet, it always does)
    re-measurement  otherwise k joins the kept actor's measurements:
                    c* <- c* + (k - c*) / (n + 1), n <- n + 1

A lucky evaluation (s high by chance) is never what the kept score records: c is measured
after the choice of candidate, on other episodes. And the kept score is the mean of all the
kept actor's measurements, not the best of many confirmations, which on a task whose returns
spread widely is biased upward (the winner's curse): on AcrobotSwingup an actor confirmed at
100.2 by the best-of rule scored 32.9 +- 99.4 over 20 fresh episodes (BENCHMARKS.md), and its
score kept later, better actors out. Comparing c and k on the same initial states removes the
spread between initial states from the comparison. A tie keeps the older actor, so a task whose
returns saturate (1000 of 1000 on the inverted pendulum) keeps the first actor that reached the
top.

With `SACConfig.eval_alongside` a point's episodes end D points later, and the kept actor they
measured may have been replaced in between: then k is not the kept actor's (`paired` False),
and the point neither replaces nor re-measures it. So a replacement is always decided on the
same episodes, and after one the kept actor is re-measured from D points on. (Comparing with c*
instead would make c* the running maximum of single confirmations again wherever replacements
come less than D points apart.)

With `SACConfig.stop_when_solved` a seed whose c* reaches `SACConfig.stop_at` (by default the
task's solved return) with n >= `SACConfig.stop_measurements` stops learning: its learner
state and kept actor no longer change (`sac_jax.train`), as Stable-Baselines3's
StopTrainingOnRewardThreshold stops a run. Just after a replacement c* is that one
confirmation, and on a task whose returns spread widely a seed stopping on it (n >= 1) can
stop on a lucky one: on AcrobotSwingup seed 0 stopped at a confirmed 65.9 with an actor that
scored 47.0 over 100 fresh episodes (an H100 run on 2026-11-28, stopping at n >= 1); the
default n >= 2 waits for one re-measurement on other episodes.
"""

from __future__ import annotations

from typing import Any, Tuple

import flax.struct
import jax
import jax.numpy as jnp


class Delivered(flax.struct.PyTreeNode):
    """The kept actor of one seed and how it was chosen.

    actor_params  parameters of the kept actor (those of the learner's actor at init)
    score         () float32, its kept score c*: the mean of its n measurements (-inf until
                  the first point)
    count         () int32, n
    env_steps     () int32, environment steps done when it was selected (-1 until then)
    """

    actor_params: Any
    score: jax.Array
    count: jax.Array
    env_steps: jax.Array


def init(actor_params) -> Delivered:
    """Nothing selected yet: the initial actor, with score -inf."""
    return Delivered(actor_params=actor_params, score=jnp.float32(-jnp.inf),
                     count=jnp.int32(0), env_steps=jnp.int32(-1))


def select(delivered: Delivered, actor_params, score: jax.Array, confirmed: jax.Array,
           kept: jax.Array, paired: jax.Array, env_steps: jax.Array
           ) -> Tuple[Delivered, jax.Array, jax.Array]:
    """One selection step (see the module docstring): `score` is the current actor's
    evaluation return s, `confirmed` its return c on the confirmation episodes, `kept` the
    return k of the kept actor on those episodes, `paired` () bool whether k is the kept
    actor's (the training loop steps all three sets of episodes as one batch, so c and k exist
    at every point; `paired` is True wherever nothing is kept yet). Returns (the kept actor
    after the step, c, or NaN where the actor was not a candidate, k, or NaN where it was not
    the kept actor's)."""
    score, confirmed, kept = (x.astype(jnp.float32) for x in (score, confirmed, kept))
    nan = jnp.float32(jnp.nan)
    measured = paired & (delivered.count > 0)  # k is the kept actor's return
    candidate = score > delivered.score
    better = candidate & paired & (confirmed > jnp.where(measured, kept, -jnp.inf))
    count = delivered.count + measured
    remeasured = delivered.replace(
        score=jnp.where(measured, delivered.score + (kept - delivered.score) / count,
                        delivered.score), count=count)
    chosen = Delivered(actor_params=actor_params, score=confirmed, count=jnp.int32(1),
                       env_steps=jnp.asarray(env_steps, jnp.int32))
    after = jax.tree_util.tree_map(lambda new, old: jnp.where(better, new, old), chosen,
                                   remeasured)
    return after, jnp.where(candidate, confirmed, nan), jnp.where(measured, kept, nan)
