"""Random numbers from Threefry bits (`jax.random.bits`), made as `jax.random` makes them from
its own: one hash of a key can then feed several draws of different kinds.

Why: on a CPU, JAX lowers each Threefry call to a loop of 5 trips whatever its size, a few
microseconds apiece in a training iteration of some hundred; `sac_jax.randomness.FromKeys`
hashes once per acting and once per learning step instead of once per draw.
"""

import jax
import jax.numpy as jnp
import numpy as np


def uniform_from_bits(bits: jax.Array, low, high) -> jax.Array:
    """float32 U(low, high) of uint32 `bits`, as `jax.random.uniform` makes them from its key's
    bits: the 23 high bits as the mantissa of a float in [1, 2), less 1, scaled."""
    one = np.array(1.0, np.float32).view(np.uint32)
    unit = jax.lax.bitcast_convert_type((bits >> 9) | one, jnp.float32) - 1.0
    low, high = jnp.asarray(low, jnp.float32), jnp.asarray(high, jnp.float32)
    return jnp.maximum(low, unit * (high - low) + low)


def normal_from_bits(bits: jax.Array) -> jax.Array:
    """float32 N(0, 1) of uint32 `bits`, as `jax.random.normal` makes them:
    sqrt(2) erfinv(u), u ~ U(lo, 1) for lo the float32 just above -1."""
    lo = np.nextafter(np.float32(-1), np.float32(0))
    return np.float32(np.sqrt(2)) * jax.lax.erf_inv(uniform_from_bits(bits, lo, 1.0))


def index_from_bits(bits: jax.Array, size: jax.Array) -> jax.Array:
    """int32 slots in [0, max(size, 1)) of uint32 `bits` (2, *shape): a 64-bit number reduced
    modulo the span, as `jax.random.randint` does with two such draws (bias ~ span^2 / 2^64)."""
    span = jnp.maximum(size, 1).astype(jnp.uint32)
    multiplier = (jnp.uint32(1 << 16) % span) ** 2 % span  # 2^32 mod span
    return ((bits[0] % span * multiplier + bits[1] % span) % span).astype(jnp.int32)
