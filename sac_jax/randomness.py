"""Where the training loop's random draws come from: one small interface, two sources.

Every iteration of `sac_jax.train` draws through a source's two methods:

    acting(k_act, k_random, iteration)  -> (random_action (n, A), action_noise (n, A))
    learning(k_learn, size, iteration)  -> (batch_index (U, B), randomness of the U updates)

`FromKeys` (what a run uses) draws them from the iteration's PRNG keys; the updates' randomness
is then U keys, from which each `sac_update` draws its noise. `Replay` hands out a recorded
stream (`Draws`, e.g. from `sac_jax.record_draws`) by iteration, the updates' randomness being
the recorded noise; a reference implementation fed the same stream reproduces the run
(tests/test_equivalence_loop.py). Evaluation and environment resets keep their keys either way.
"""

from __future__ import annotations

from typing import Dict, Tuple

import flax.struct
import jax
import jax.numpy as jnp

from sac_jax import replay_buffer as rb


class Draws(flax.struct.PyTreeNode):
    """The random draws of one training iteration (n = num_envs, A = action size,
    U = updates_per_step, B = batch_size). A recorded stream holds them for every iteration of
    a run, each field with a leading axis T = total iterations (`sac_jax.record_draws`).

    random_action (n, A)  U(low, high): the actions during the prefill
    action_noise (n, A)   standard normal eps of the policy's action a = f(eps; s) afterwards
    batch_index (U, B)    int32 replay slots of the iteration's U minibatches
    update_noise          for each of the U `sac_update`s the dict of `sample_noise`, every
                          leaf with a leading axis U
    Each iteration holds all of them; the prefill uses no batch_index, update_noise or
    action_noise, and training no random_action.
    """

    random_action: jax.Array
    action_noise: jax.Array
    batch_index: jax.Array
    update_noise: Dict[str, jax.Array]


class FromKeys:
    """Draws from PRNG keys: the source of every run."""

    def __init__(self, num_envs: int, action_low, action_high, updates: int, batch_size: int):
        self._n, self._updates, self._batch_size = num_envs, updates, batch_size
        self._low, self._high = jnp.asarray(action_low), jnp.asarray(action_high)

    def acting(self, k_act: jax.Array, k_random: jax.Array, iteration: jax.Array
               ) -> Tuple[jax.Array, jax.Array]:
        """U(low, high) actions from k_random; N(0, 1) noise eps (n, A) from k_act."""
        shape = (self._n,) + self._low.shape
        return (jax.random.uniform(k_random, shape, minval=self._low, maxval=self._high),
                jax.random.normal(k_act, shape, jnp.float32))

    def learning(self, k_learn: jax.Array, size: jax.Array, iteration: jax.Array
                 ) -> Tuple[jax.Array, jax.Array]:
        """Slots drawn uniformly from a buffer of `size`, and U keys for the updates' noise."""
        k_batch, k_noise = jax.random.split(k_learn)
        return (rb.sample_indices(k_batch, size, (self._updates, self._batch_size)),
                jax.random.split(k_noise, self._updates))


class Replay:
    """A recorded stream of `Draws` (leading axis: the run's iterations), handed out by
    iteration; the keys are ignored. Build it with `replay`, which checks the stream's shapes."""

    def __init__(self, draws: Draws):
        self.draws = draws

    def _at(self, iteration: jax.Array) -> Draws:
        return jax.tree_util.tree_map(lambda x: x[iteration], self.draws)

    def acting(self, k_act, k_random, iteration):
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
