"""A fixed-capacity ring buffer of transitions held in device memory, as a pytree.

`init`, `add` and `sample` are pure: `add` returns a new buffer (inside `lax.scan` XLA updates
the carried arrays in place); `sample` is `gather` at `sample_indices`, so a caller can also
gather at slots drawn elsewhere (a recorded stream, see `sac_jax.train.Draws`). Every array
of the stored pytree has a leading capacity axis C.
"""

from __future__ import annotations

from typing import Tuple, Union

import flax.struct
import jax
import jax.numpy as jnp

from sac_jax.random_bits import index_from_bits


class Transition(flax.struct.PyTreeNode):
    """(s, a, r, s', terminated). `action` in environment units; `next_obs` is the true
    observation after the step (the final one on truncation), so targets can bootstrap there.
    It is stored in every slot although within an episode it repeats the next slot's obs: an
    exact store of each observation once saves nothing in a fixed-shape buffer (BENCHMARKS.md,
    "Each observation stored once?", `benchmarks/observation_once.py`).
    Shapes with a batch B: obs (B, O), action (B, A), reward (B,), next_obs (B, O),
    terminated (B,) float32 in {0, 1}."""

    obs: jax.Array
    action: jax.Array
    reward: jax.Array
    next_obs: jax.Array
    terminated: jax.Array


class ReplayBuffer(flax.struct.PyTreeNode):
    """`data`: a pytree of arrays (C, ...); `position`: next slot to write; `size`: filled slots."""

    data: Transition
    position: jax.Array
    size: jax.Array

    @property
    def capacity(self) -> int:
        return jax.tree_util.tree_leaves(self.data)[0].shape[0]


def init(capacity: int, example: Transition) -> ReplayBuffer:
    """An empty buffer of `capacity` slots shaped and typed like one unbatched `example`."""
    data = jax.tree_util.tree_map(
        lambda x: jnp.zeros((capacity,) + jnp.shape(x), jnp.asarray(x).dtype), example)
    return ReplayBuffer(data=data, position=jnp.int32(0), size=jnp.int32(0))


def add(buffer: ReplayBuffer, batch: Transition) -> ReplayBuffer:
    """Writes the n transitions of `batch` (leading axis n) at slots position..position+n-1,
    overwriting the oldest once full. C must be a multiple of n, so a batch never straddles the
    end; the write is one `dynamic_update_slice`, done in place inside `lax.scan`."""
    capacity = buffer.capacity
    n = jax.tree_util.tree_leaves(batch)[0].shape[0]
    if capacity % n:
        raise ValueError(f"replay capacity {capacity} is not a multiple of the batch of {n} "
                         "transitions added at once")
    data = jax.tree_util.tree_map(
        lambda d, x: jax.lax.dynamic_update_slice_in_dim(d, x.astype(d.dtype), buffer.position, 0),
        buffer.data, batch)
    return ReplayBuffer(data=data,
                        position=(buffer.position + n) % capacity,
                        size=jnp.minimum(buffer.size + n, capacity))


def sample_indices(key: jax.Array, size: jax.Array, batch_shape: Union[int, Tuple[int, ...]]
                   ) -> jax.Array:
    """int32 slots of shape `batch_shape` drawn uniformly with replacement from the filled slots
    [0, size) (slot 0 while size is 0), from one Threefry hash of `key`."""
    shape = (batch_shape,) if isinstance(batch_shape, int) else tuple(batch_shape)
    return index_from_bits(jax.random.bits(key, (2,) + shape, jnp.uint32), size)


def gather(buffer: ReplayBuffer, indices: jax.Array) -> Transition:
    """The transitions in slots `indices` (any integer shape), with leading axes that shape."""
    return jax.tree_util.tree_map(lambda d: d[indices], buffer.data)


def sample(buffer: ReplayBuffer, key: jax.Array, batch_shape: Union[int, Tuple[int, ...]]
           ) -> Transition:
    """Transitions drawn uniformly with replacement from the filled slots [0, size), with leading
    axes `batch_shape` (B or, for several minibatches at once, (U, B)): `gather` at
    `sample_indices`. Sampling an empty buffer returns slot 0 (zeros); `make_train` never does."""
    return gather(buffer, sample_indices(key, buffer.size, batch_shape))
