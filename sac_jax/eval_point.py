"""An evaluation point of the training loop (`sac_jax.train`): the episodes it steps, the two
actors acting in them, and the selection of the delivered actor on their returns
(`sac_jax.selection`); with `SACConfig.eval_alongside`, the evaluations still under way
(`Pending`), stepped once per training iteration and scored D points later.

A point steps 2 E episodes, E = eval_episodes + confirm_episodes, as one batch (leading axis
2 E):

    rows 0 .. eval_episodes - 1     the point's actor from the evaluation's initial states,
                                    drawn from k_eval (its score s)
    rows eval_episodes .. E - 1     the point's actor from fresh initial states, drawn from
                                    k_confirm (its confirmed return c)
    rows E .. 2 E - 1               the kept actor from the same E initial states (its return
                                    k on the confirmation's rows)

So the confirmation is computed at every point (it counts for a candidate only). One batch
keeps one traced copy of the environment's step for evaluation instead of two: the `fast`
preset's chunk compiled in 13.8 s instead of 18.3 s on 2 CPU cores and trained to the same
solved steps (4 seeds: runs of 2.0-2.6 s either way); under `vmap` (many seeds) a per-candidate
branch was computed for every seed anyway, and one batch halves the sequential steps of a point.
"""

from __future__ import annotations

import dataclasses
from typing import Any, List, Optional, Tuple

import flax.struct
import jax
import jax.numpy as jnp

from sac_jax import selection
from sac_jax.agent import Agent
from sac_jax.config import SACConfig
from sac_jax.evaluation import Episodes, begin, initial_states, run_episodes, step_episodes
from sac_jax.updates import mean_over_devices


class Pending(flax.struct.PyTreeNode):
    """The evaluations under way with `SACConfig.eval_alongside`, one slot per evaluation point
    whose episodes are still being stepped: `actor_params` (leading axis 2 D) the actors each
    slot evaluates, the point's actor at 2 d and the kept actor at 2 d + 1, `episodes` the
    `Episodes` of all slots in one batch, slot d's 2 E (`EvalPoints.start`) at rows 2 d E to
    2 (d + 1) E - 1, `env_steps` (D,) int32 each point's environment steps, 0 where the slot
    holds no evaluation (a point has done at least eval_every steps), `kept_steps` (D,) int32
    the `env_steps` of the kept actor the slot evaluates (`selection.Delivered`).
    One batch gives one vmapped environment step: a batch per slot, stepped under a `vmap`
    over the slots, made AcrobotSwingup's two programs compile in 32.9 s instead of 27.9 s
    (15.8 s without `eval_alongside`; 2 CPU cores, one compile each, ad hoc)."""

    actor_params: Any
    episodes: Episodes
    env_steps: jax.Array
    kept_steps: jax.Array

    @property
    def active(self) -> jax.Array:
        """(D,) bool: whether each slot holds an evaluation."""
        return self.env_steps > 0


def _stacked(actor, kept):
    """A point's two actors, its own and the kept one, stacked (group 0 and 1)."""
    return jax.tree_util.tree_map(lambda *x: jnp.stack(x), actor, kept)


@dataclasses.dataclass(frozen=True)
class EvalPoints:
    """The evaluation points of `config`'s run on `env`. Every method is pure and jit-able;
    `agent` is the run's agent (with the runner's traced hyperparameters, if any)."""

    config: SACConfig
    env: Any

    @property
    def episodes(self) -> int:
        """E, the episodes of one actor at a point."""
        return self.config.eval_episodes + self.config.confirm_episodes

    @property
    def depth(self) -> int:
        """D, the points whose evaluations are under way at once with `eval_alongside`
        (ceil(episode steps / iterations per point), so that a point's episodes have ended D
        points later); 0 without."""
        if not self.config.eval_alongside:
            return 0
        return -(-self.env.max_episode_steps // self.config.iterations_per_eval)

    def start(self, k_eval: jax.Array, k_confirm: jax.Array) -> Episodes:
        """A point's 2 E episodes before their first step (see the module docstring); the
        evaluation's initial states as `sac_jax.evaluate` draws them from `k_eval`."""
        cfg = self.config
        starts = initial_states(self.env, jnp.concatenate([
            jax.random.split(k_eval, cfg.eval_episodes),
            jax.random.split(k_confirm, cfg.confirm_episodes)]))
        return begin(jax.tree_util.tree_map(lambda x: jnp.concatenate([x, x]), starts))

    def evaluate(self, agent: Agent, actor, delivered: selection.Delivered,
                 pending: Optional[Pending], k_eval: jax.Array, k_confirm: jax.Array,
                 index: jax.Array, env_steps: jax.Array
                 ) -> Tuple[selection.Delivered, List[jax.Array], Optional[Pending]]:
        """Point `index` (of `config.num_evals`) after `env_steps` steps, with the learner's
        `actor`: (delivered actor after the point, [evaluation return, confirmed return, kept
        actor's return], pending). Without `eval_alongside` the point's episodes run to their
        end here; with it they start in a slot of `pending`, and the returns are those of the
        point D earlier, NaN where there is none (at the last point every evaluation under way
        runs to its end, and they are the last point's)."""
        point = self.start(k_eval, k_confirm)
        if self.depth:
            return self._alongside(agent, actor, delivered, pending, point, index, env_steps)
        returns = run_episodes(self.env, self._act_by_group(
            agent, _stacked(actor, delivered.actor_params)), point).returns
        delivered, *returns = self._select(delivered, actor, returns, jnp.bool_(True), env_steps)
        return delivered, returns, pending

    def init_pending(self, key: jax.Array, actor_params) -> Optional[Pending]:
        """`Pending` with D empty slots (None without `eval_alongside`): their placeholder
        episodes, from `key`, have ended; `actor_params` gives the actors' shapes."""
        depth = self.depth
        if not depth:
            return None
        placeholder = self.start(*jax.random.split(key))
        rows = lambda x: jnp.concatenate([x] * depth)
        return Pending(
            actor_params=jax.tree_util.tree_map(
                lambda x: jnp.broadcast_to(x, (2 * depth,) + x.shape), actor_params),
            episodes=Episodes(*jax.tree_util.tree_map(rows, placeholder[:2]),
                              jnp.zeros(depth * 2 * self.episodes, bool),
                              rows(placeholder.returns), placeholder.steps),
            env_steps=jnp.zeros(depth, jnp.int32), kept_steps=jnp.zeros(depth, jnp.int32))

    def step_pending(self, agent: Agent, pending: Pending) -> Pending:
        """One step of every evaluation under way (a training iteration's share)."""
        return pending.replace(episodes=step_episodes(
            self.env, self._act_by_group(agent, pending.actor_params), pending.episodes))

    def _mean_return(self, returns: jax.Array) -> jax.Array:
        """Mean of deterministic returns (over all devices' episodes in a data-parallel run,
        so every device selects alike)."""
        return mean_over_devices(self.config, jnp.mean(returns))

    def _act_by_group(self, agent: Agent, actors):
        """Deterministic actions for rows in groups of E, group g acting with actor g
        (`actors`: parameters with a leading axis of groups)."""
        def act(obs):
            by_group = obs.reshape((-1, self.episodes) + obs.shape[1:])
            return jax.vmap(agent.act)(actors, by_group).reshape(obs.shape[0], -1)
        return act

    def _select(self, delivered, actor, returns: jax.Array, paired: jax.Array,
                env_steps: jax.Array):
        """The selection step (`sac_jax.selection`) on one point's 2 E returns: (kept actor,
        evaluation return, confirmed return, kept actor's return)."""
        n, e = self.config.eval_episodes, self.episodes
        score = self._mean_return(returns[:n])
        kept, confirmed, kept_return = selection.select(
            delivered, actor, score, self._mean_return(returns[n:e]),
            self._mean_return(returns[e + n:]), paired, env_steps)
        return kept, score, confirmed, kept_return

    def _select_pending(self, delivered, pending: Pending, slot: jax.Array):
        """`_select` on the evaluation in `slot` if it holds one (else NaN returns); its kept
        actor's returns count only if that is still the kept actor."""
        nan = jnp.float32(jnp.nan)
        out = self._select(
            delivered, jax.tree_util.tree_map(lambda x: x[2 * slot], pending.actor_params),
            pending.episodes.returns.reshape(self.depth, 2 * self.episodes)[slot],
            pending.kept_steps[slot] == delivered.env_steps, pending.env_steps[slot])
        keep = lambda new, old: jnp.where(pending.active[slot], new, old)
        return (jax.tree_util.tree_map(keep, out[0], delivered),) + tuple(
            keep(x, nan) for x in out[1:])

    def _alongside(self, agent: Agent, actor, delivered, old: Pending, point: Episodes,
                   index: jax.Array, env_steps: jax.Array):
        """Scores the evaluation that has ended in this point's slot, starts this point's
        there, and at the last point runs every evaluation under way to its end and selects
        on them oldest first."""
        depth, rows = self.depth, 2 * self.episodes
        slot = index % depth
        delivered, *returns = self._select_pending(delivered, old, slot)
        put = lambda all_rows, new: jax.lax.dynamic_update_slice_in_dim(
            all_rows, new, slot * rows, 0)
        pending = Pending(
            actor_params=jax.tree_util.tree_map(
                lambda all_, two: jax.lax.dynamic_update_slice_in_dim(all_, two, 2 * slot, 0),
                old.actor_params, _stacked(actor, delivered.actor_params)),
            episodes=Episodes(*jax.tree_util.tree_map(put, old.episodes[:4], point[:4]),
                              old.episodes.steps),
            env_steps=old.env_steps.at[slot].set(env_steps),
            kept_steps=old.kept_steps.at[slot].set(delivered.env_steps))

        def drain(args):
            delivered, _, pending = args
            pending = pending.replace(episodes=run_episodes(
                self.env, self._act_by_group(agent, pending.actor_params),
                pending.episodes._replace(steps=jnp.int32(0))))

            def fold(delivered, s):
                delivered, *returns = self._select_pending(delivered, pending, s)
                return delivered, returns

            oldest_first = (slot + 1 + jnp.arange(depth)) % depth
            delivered, returns = jax.lax.scan(fold, delivered, oldest_first)
            return (delivered, [r[-1] for r in returns],
                    pending.replace(env_steps=jnp.zeros_like(pending.env_steps)))

        return jax.lax.cond(index == self.config.num_evals - 1, drain, lambda args: args,
                            (delivered, returns, pending))
