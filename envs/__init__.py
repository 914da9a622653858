"""JAX environments: MJX inverted pendulums and a pure-JAX Pendulum-v1.

    import jax, envs
    env = envs.make("InvertedPendulum-v5")
    state = jax.jit(env.reset)(jax.random.key(0))
    state = jax.jit(env.step)(state, jax.numpy.zeros(env.action_size))

See docs/environments.md for the interface and the list of environments.
``envs.to_brax(env)`` exposes an environment as a ``brax.envs.Env`` (envs/brax_adapter.py);
Brax is imported on its first use only.
"""

from envs.registry import DEFAULT_ENV, EnvSpec, make, options, registered, spec
from envs.types import Env, EnvState
from envs.vector import VectorEnv, VectorState, VectorStep

__all__ = [
    "DEFAULT_ENV",
    "Env",
    "EnvSpec",
    "EnvState",
    "VectorEnv",
    "VectorState",
    "VectorStep",
    "make",
    "options",
    "registered",
    "spec",
    "to_brax",
]


def __getattr__(name: str):
    """Loads ``to_brax`` (and with it Brax) on first access, so ``import envs`` stays light."""
    if name == "to_brax":
        from envs import _lean_import

        with _lean_import.mjx_import():  # Brax imports MJX
            from envs.brax_adapter import to_brax

        return to_brax
    raise AttributeError(f"module 'envs' has no attribute {name!r}")
