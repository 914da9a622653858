"""JAX environments: MJX inverted pendulums and a pure-JAX Pendulum-v1.

    import jax, envs
    env = envs.make("InvertedPendulum-v5")
    state = jax.jit(env.reset)(jax.random.key(0))
    state = jax.jit(env.step)(state, jax.numpy.zeros(env.action_size))

See docs/environments.md for the interface and the list of environments.
"""

from envs.registry import DEFAULT_ENV, make, options, registered
from envs.types import Env, EnvState
from envs.vector import VectorEnv, VectorState, VectorStep

__all__ = [
    "DEFAULT_ENV",
    "Env",
    "EnvState",
    "VectorEnv",
    "VectorState",
    "VectorStep",
    "make",
    "options",
    "registered",
]
