"""MJX forward dynamics that skip the constraint solver for a batch with no constraint active.

MJX keeps every constraint row a model can have, e.g. one per limited joint, and zeroes the
Jacobian row J_i and reference acceleration aref_i of a row that is not active (a joint
inside its range). If every row of every instance is zero, the solver's constraint cost

    s(J qacc - aref) = s(0) = 0   for every qacc,

so its minimiser is the unconstrained acceleration, qacc = qacc_smooth, with zero constraint
force: what C MuJoCo returns when it has no constraint rows (nefc = 0). MJX's solver still
runs its iterations to find that, and on a GPU they are most of a pendulum step's latency
(H100: 1,280 balancing pendulums evaluated for 1,000 steps in 1.2 s with the skip, 3.8 s
without); in an evaluation of balancing pendulums no limit is ever active.

`forward` is `mjx.forward` with `solve` in place of MJX's solver. `solve` is written for one
instance and batches with `jax.custom_batching.custom_vmap`: under `vmap`, however deeply
nested, the instances are merged into one batch and a single `lax.cond` on "any row active
anywhere in the batch" either runs MJX's solver on all of them or returns qacc_smooth for
all. A plain `vmap` would turn a per-instance `cond` into a `select` that runs the solver
anyway. The states agree with MJX's solver bit for bit where a row is active and, where none
is, to within its rounding (`tests/test_idle_solver.py`). No reverse-mode derivative: nothing here
differentiates through the simulator.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from envs._mjx import mjx, mjx_forward, mjx_sensor, mjx_solver


def forward(m: mjx.Model, d: mjx.Data) -> mjx.Data:
    """``mjx.forward(m, d)`` (MJX 3.17's sequence of stages) with `solve` as its solver."""
    d = mjx_forward.fwd_position(m, d)
    d = mjx_sensor.sensor_pos(m, d)
    d = mjx_forward.fwd_velocity(m, d)
    d = mjx_sensor.sensor_vel(m, d)
    d = mjx_forward.fwd_actuation(m, d)
    d = mjx_forward.fwd_acceleration(m, d)
    if d._impl.efc_J.size == 0:
        return d.replace(qacc=d.qacc_smooth)
    return mjx_sensor.sensor_acc(m, solve(m, d))


def _unconstrained(d: mjx.Data) -> mjx.Data:
    """What MJX's solver returns when no row is active: qacc_smooth and zero forces."""
    return d.tree_replace({
        "qacc": d.qacc_smooth,
        "qfrc_constraint": jnp.zeros_like(d.qfrc_constraint),
        "_impl.efc_force": jnp.zeros_like(d._impl.efc_force),
    })


def solve(m: mjx.Model, d: mjx.Data) -> mjx.Data:
    """MJX's constraint solver on one instance's ``d``, skipped under `vmap` for a whole batch
    whose rows are all inactive (J = 0 and aref = 0); see the module docstring."""

    @jax.custom_batching.custom_vmap
    def solve_batch(d):  # every leaf with a leading batch axis B
        idle = ~(jnp.any(d._impl.efc_J != 0) | jnp.any(d._impl.efc_aref != 0))
        return jax.lax.cond(idle, _unconstrained, jax.vmap(lambda x: mjx_solver.solve(m, x)), d)

    @solve_batch.def_vmap
    def merge_axes(axis_size, in_batched, d):
        """Batch axis A over leaves (B, ...): solve the A * B instances as one batch."""
        d = jax.tree_util.tree_map(
            lambda x, b: x if b else jnp.broadcast_to(x, (axis_size,) + x.shape), d, in_batched[0])
        merged = lambda x: x.reshape((x.shape[0] * x.shape[1],) + x.shape[2:])
        out = solve_batch(jax.tree_util.tree_map(merged, d))
        split = lambda x: x.reshape((axis_size, x.shape[0] // axis_size) + x.shape[1:])
        out = jax.tree_util.tree_map(split, out)
        return out, jax.tree_util.tree_map(lambda _: True, out)

    one = solve_batch(jax.tree_util.tree_map(lambda x: x[None], d))
    return jax.tree_util.tree_map(lambda x: x[0], one)
