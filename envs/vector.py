"""Batched environments with automatic reset, for ``lax.scan`` training loops.

``VectorEnv(env, n)`` runs n independent copies of ``env`` with ``jax.vmap``.  When copy i
terminates or truncates, its next state is a fresh ``env.reset(k_i)`` with a new key k_i
split from ``VectorState.key`` (never a cached initial state), and ``VectorStep`` reports
both the observation to act on next and the true final observation of the ended episode.
"""

from __future__ import annotations

from typing import Optional

import jax
import jax.numpy as jnp
from flax import struct

from envs._validate import is_positive_int
from envs.types import Env, EnvState


class VectorState(struct.PyTreeNode):
    """State of a VectorEnv of n copies.

    Attributes:
        env_state: EnvState with a leading batch axis n on every leaf.
        key: PRNG key for the resets of ended episodes.
        episode_return: (n,) float32, return so far of each running episode.
        episode_length: (n,) int32, steps so far of each running episode.
    """

    env_state: EnvState
    key: jax.Array
    episode_return: jax.Array
    episode_length: jax.Array


class VectorStep(struct.PyTreeNode):
    """What one ``VectorEnv.step`` reports, all with leading axis n.

    Attributes:
        obs: (n, obs_size) observation to act on next: a fresh reset observation where
            the episode ended (``done``), else ``final_obs``.
        final_obs: (n, obs_size) observation reached by this step, before any reset.
        reward, terminated, truncated: (n,) of this step.
        done: (n,) bool, ``terminated | truncated``.
        episode_return: (n,) float32, Σ rewards of the episode including this step.
        episode_length: (n,) int32, number of steps of the episode including this step.
            Both are meaningful where ``done``.
    """

    obs: jax.Array
    final_obs: jax.Array
    reward: jax.Array
    terminated: jax.Array
    truncated: jax.Array
    done: jax.Array
    episode_return: jax.Array
    episode_length: jax.Array


def where_rows(mask: jax.Array, new, old):
    """The batched pytree with row i of every leaf from `new` where mask[i], else from `old`.

    mask (n,) bool; `new` and `old` pytrees of the same structure, every leaf with leading axis n.
    """
    return jax.tree_util.tree_map(
        lambda a, b: jnp.where(mask.reshape((-1,) + (1,) * (a.ndim - 1)), a, b), new, old)


class VectorEnv:
    """n copies of ``env`` stepped in lock-step, with auto-reset (see the module docstring).

    ``reset_axis``: the name of a ``vmap`` axis that ``step`` runs under (e.g. the seeds of
    ``jax.vmap(train, axis_name="seeds")``), or None. Fresh states are computed only on steps
    where an episode ended, in a ``lax.cond``; under ``vmap`` a predicate that differs along
    the mapped axis makes the ``cond`` compute both branches, so every step would reset every
    copy. With ``reset_axis`` the predicate is whether an episode ended anywhere along that
    axis, the same for all, and the ``cond`` stays a branch. It matters where a reset costs
    many steps: Playground's CheetahRun settles each fresh state over 200 physics steps, and 2
    seeds vmapped on one device trained 3,072 steps in 13.3 s with it, 89.2 s without, where one
    seed took 8.3 s (2 CPU cores, `--preset PendulumSwingup --env playground/CheetahRun
    --num-envs 32 --total-steps 4096 --eval-episodes 1 --confirm-episodes 1`, ad hoc).
    """

    def __init__(self, env: Env, num_envs: int, reset_axis: Optional[str] = None):
        if not is_positive_int(num_envs):
            raise ValueError(f"num_envs must be an int >= 1, got {num_envs!r}")
        self._env = env
        self._num_envs = int(num_envs)
        self._reset_axis = reset_axis

    @property
    def env(self) -> Env:
        return self._env

    @property
    def num_envs(self) -> int:
        return self._num_envs

    def __repr__(self) -> str:
        return f"<VectorEnv {self._env.name} x{self._num_envs}>"

    def _reset_all(self, key: jax.Array) -> EnvState:
        """Batched EnvState of n fresh episodes, one key each split from ``key``."""
        return jax.vmap(self._env.reset)(jax.random.split(key, self._num_envs))

    def reset(self, key: jax.Array) -> VectorState:
        """Start n episodes; key: PRNG key."""
        key, reset_key = jax.random.split(key)
        return VectorState(
            env_state=self._reset_all(reset_key),
            key=key,
            episode_return=jnp.zeros(self._num_envs, jnp.float32),
            episode_length=jnp.zeros(self._num_envs, jnp.int32),
        )

    def step(self, vstate: VectorState, actions: jax.Array) -> tuple[VectorState, VectorStep]:
        """Step all copies with actions (n, action_size); reset those whose episode ended.

        Fresh states are only computed (for all n copies, then selected) on steps where at
        least one episode ended.
        """
        stepped = jax.vmap(self._env.step)(vstate.env_state, actions)
        done = stepped.terminated | stepped.truncated
        episode_return = vstate.episode_return + stepped.reward
        episode_length = vstate.episode_length + 1
        key, reset_key = jax.random.split(vstate.key)

        ended = jnp.any(done)
        if self._reset_axis is not None:  # one predicate along the axis: `cond` stays a branch
            ended = jax.lax.psum(ended.astype(jnp.int32), self._reset_axis) > 0
        env_state = jax.lax.cond(
            ended, lambda state: where_rows(done, self._reset_all(reset_key), state),
            lambda state: state, stepped)
        next_vstate = VectorState(
            env_state=env_state,
            key=key,
            episode_return=jnp.where(done, 0.0, episode_return),
            episode_length=jnp.where(done, 0, episode_length),
        )
        info = VectorStep(
            obs=env_state.obs,
            final_obs=stepped.obs,
            reward=stepped.reward,
            terminated=stepped.terminated,
            truncated=stepped.truncated,
            done=done,
            episode_return=episode_return,
            episode_length=episode_length,
        )
        return next_vstate, info
