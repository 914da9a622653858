"""Our environments as Brax environments, so Brax's own trainers can run on the same physics.

    benv = envs.to_brax(envs.make("InvertedPendulum-v5"))          # a brax.envs.Env
    benv = brax.envs.training.wrap(benv, episode_length=benv.max_episode_steps)

Brax's conventions, and how each is met:

* Actions lie in [-1, 1] (Brax's policies squash with tanh); the adapter maps them affinely
  onto our bounds before our ``step`` (which clips and applies the non-finite rule)::

      a_env = low + (a + 1) (high - low) / 2

* ``State.done`` is the MDP's termination alone (our ``terminated``, as 0./1. float32).  The
  time limit is the job of Brax's ``EpisodeWrapper``: with ``episode_length =
  max_episode_steps`` it sets ``done = terminated or steps >= episode_length`` and
  ``info['truncation'] = (steps >= episode_length) and not terminated``, which are Gymnasium's
  ``terminated or truncated`` and its bootstrapping rule (a truncated, non-terminal step keeps
  the value of its successor).  Reporting our ``truncated`` as ``done`` here as well would make
  that wrapper read the time limit as a termination.
* ``State.pipeline_state`` is our whole :class:`envs.EnvState`, so ``AutoResetWrapper``
  restores it (step counter included) together with the observation.

Brax is imported by this module only; ``import envs`` stays free of it (``envs.to_brax`` loads
this module on first use).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from brax.envs.base import Env as BraxEnv
from brax.envs.base import State

from envs.types import Env


class BraxAdapter(BraxEnv):
    """A ``brax.envs.base.Env`` that steps one of our environments (see the module docstring).

    ``reset(rng) -> State`` and ``step(state, action) -> State`` take the same shapes as our
    environment's: a PRNG key, and an action of shape (action_size,) in [-1, 1].
    """

    def __init__(self, env: Env):
        if not isinstance(env, Env):
            raise TypeError(
                f"envs.to_brax expects an envs.Env (for example envs.make('InvertedPendulum-v5')), "
                f"got {type(env).__name__}: {env!r}"
            )
        self._env = env
        self._low = jnp.asarray(env.action_low)
        self._half_range = jnp.asarray((env.action_high - env.action_low) / 2)

    @property
    def env(self) -> Env:
        """The wrapped environment."""
        return self._env

    @property
    def observation_size(self) -> int:
        return self._env.observation_size

    @property
    def action_size(self) -> int:
        return self._env.action_size

    @property
    def max_episode_steps(self) -> int:
        """Our time limit: the ``episode_length`` to give Brax's ``EpisodeWrapper``."""
        return self._env.max_episode_steps

    @property
    def backend(self) -> str:
        """Our own physics code (MJX for the MuJoCo tasks), not one of Brax's pipelines."""
        return "sac-jax"

    def __repr__(self) -> str:
        return f"<BraxAdapter of {self._env!r}>"

    def reset(self, rng: jax.Array) -> State:
        s = self._env.reset(rng)
        return State(pipeline_state=s, obs=s.obs, reward=s.reward,
                     done=jnp.zeros((), jnp.float32), metrics={}, info={})

    def step(self, state: State, action: jax.Array) -> State:
        env_action = self._low + (jnp.asarray(action) + 1.0) * self._half_range
        s = self._env.step(state.pipeline_state, env_action)
        return state.replace(pipeline_state=s, obs=s.obs, reward=s.reward,
                             done=s.terminated.astype(jnp.float32))


def to_brax(env: Env) -> BraxAdapter:
    """``env`` (an :class:`envs.Env`) as a ``brax.envs.Env``; see the module docstring.

    Raises:
        TypeError: ``env`` is not an :class:`envs.Env`.
    """
    return BraxAdapter(env)
