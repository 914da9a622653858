"""Where the training loop's random draws come from: one small interface, two sources.

Every iteration of `sac_jax.train` draws through a source's two methods:

    acting(k_act, iteration)           -> (random_action (n, A), action_noise (n, A))
    learning(k_learn, size, iteration) -> (batch_index (U, B), update_noise of the U updates)

`FromKeys` (what a run uses) draws each method's numbers from its key with one Threefry hash
(`jax.random.bits`), and turns the bits into uniforms, normals and slots as `jax.random.uniform`,
`normal` and `randint` do (`uniform_from_bits`, `normal_from_bits`, `index_from_bits`). On a
CPU each Threefry call is a loop of 5 trips whatever its size; one iteration drew through 13 of
them, 4 now (with the iteration's split and the environments'). `Replay` hands out a recorded
stream (`Draws`, e.g. from `sac_jax.record_draws`) by iteration; a reference implementation fed
the same stream reproduces the run (tests/test_equivalence_loop.py). Evaluation and
environment resets keep their keys either way.
"""

from __future__ import annotations

from typing import Dict, Tuple

import flax.struct
import jax
import jax.numpy as jnp

from sac_jax import updates
from sac_jax.random_bits import index_from_bits, normal_from_bits, uniform_from_bits


class Draws(flax.struct.PyTreeNode):
    """The random draws of one training iteration (n = num_envs, A = action size,
    U = updates_per_step, B = batch_size). A recorded stream holds them for every iteration of
    a run, each field with a leading axis T = total iterations (`sac_jax.record_draws`).

    random_action (n, A)  U(low, high): the actions during the prefill
    action_noise (n, A)   standard normal eps of the policy's action a = f(eps; s) afterwards
    batch_index (U, B)    int32 replay slots of the iteration's U minibatches
    update_noise          for each of the U `sac_update`s the dict of `sample_noise` (the
                          entries its configuration reads), every leaf with a leading axis U
    Each iteration holds all of them; the prefill uses no batch_index, update_noise or
    action_noise, and training no random_action.
    """

    random_action: jax.Array
    action_noise: jax.Array
    batch_index: jax.Array
    update_noise: Dict[str, jax.Array]


class FromKeys:
    """Draws from PRNG keys: the source of every run. Each method hashes its key once
    (`jax.random.bits`) and splits the bits into its draws."""

    def __init__(self, agent, num_envs: int, updates: int, batch_size: int):
        self._agent, self._updates, self._batch_size = agent, updates, batch_size
        self._shape = (num_envs, agent.action_size)

    def acting(self, k_act: jax.Array, iteration: jax.Array) -> Tuple[jax.Array, jax.Array]:
        """U(low, high) actions and N(0, 1) noise eps, each (n, A), from k_act."""
        bits = jax.random.bits(k_act, (2,) + self._shape, jnp.uint32)
        return (uniform_from_bits(bits[0], self._agent.action_low, self._agent.action_high),
                normal_from_bits(bits[1]))

    def learning(self, k_learn: jax.Array, size: jax.Array, iteration: jax.Array
                 ) -> Tuple[jax.Array, Dict[str, jax.Array]]:
        """Slots (U, B) drawn uniformly from a buffer of `size`, and the U updates' noise."""
        words = updates.noise_words(self._agent, self._batch_size)
        shape = (self._updates, 2 * self._batch_size + words)
        bits = jax.random.bits(k_learn, shape, jnp.uint32)
        slots = bits[:, :2 * self._batch_size].reshape(self._updates, 2, self._batch_size)
        return (index_from_bits(jnp.swapaxes(slots, 0, 1), size),
                jax.vmap(lambda b: updates.noise_from_bits(self._agent, b, self._batch_size))(
                    bits[:, 2 * self._batch_size:]))


class Replay:
    """A recorded stream of `Draws` (leading axis: the run's iterations), handed out by
    iteration; the keys are ignored. Build it with `replay`, which checks the stream's shapes."""

    def __init__(self, draws: Draws):
        self.draws = draws

    def _at(self, iteration: jax.Array) -> Draws:
        return jax.tree_util.tree_map(lambda x: x[iteration], self.draws)

    def acting(self, k_act, iteration):
        draws = self._at(iteration)
        return draws.random_action, draws.action_noise

    def learning(self, k_learn, size, iteration):
        draws = self._at(iteration)
        return draws.batch_index, draws.update_noise


def check(draws: Draws, expected: Draws) -> None:
    """ValueError naming the first field of `draws` whose shape (or kind: integer slots, float
    noise) differs from `expected` (shapes of the stream `record_draws` makes)."""
    paths = jax.tree_util.tree_flatten_with_path(expected)[0]
    leaves, treedef = jax.tree_util.tree_flatten(draws)
    if treedef != jax.tree_util.tree_structure(expected):
        raise ValueError(f"draws has structure {treedef}, expected that of record_draws: "
                         f"{jax.tree_util.tree_structure(expected)}")
    for (path, want), got in zip(paths, leaves):
        kind = jnp.integer if jnp.issubdtype(want.dtype, jnp.integer) else jnp.floating
        if jnp.shape(got) != want.shape or not jnp.issubdtype(jnp.result_type(got), kind):
            raise ValueError(f"draws{jax.tree_util.keystr(path)} has shape {jnp.shape(got)} and "
                             f"dtype {jnp.result_type(got)}, expected shape {want.shape} of "
                             f"{kind.__name__} (leading axis: the run's iterations)")
