"""`envs.idle_solver.forward` against `mjx.forward` and C MuJoCo's `mj_forward`.

States of InvertedPendulum-v5 (slider range [-1, 1], hinge range [-90, 90] degrees) with random
velocities and controls: "idle" ones with every joint inside its range, and a "mixed" batch
where instance 0's cart is past the slider's end (its limit row active). Asserted:
  mixed batch: every output leaf of every instance is the same bit for bit as `mjx.forward`'s
      (the batch ran MJX's solver), flat or under nested `vmap`;
  idle batch: qacc is qacc_smooth exactly and the constraint forces are exactly zero (the
      solver was skipped), MJX's solver agrees to 1e-5 relative (measured: it stops within a
      few float32 ulps of qacc_smooth), and so does C MuJoCo, which has no constraint row;
  the skip is a real branch: `vmap(vmap(forward))` holds a `cond` on one scalar predicate.
"""

from __future__ import annotations

import jax
import jax.extend.core
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

import envs
from envs._mjx import mjx
from envs.idle_solver import forward

N = 8


@pytest.fixture(scope="module")
def env():
    return envs.make("InvertedPendulum-v5")


def batch(env, active: bool):
    """(N,) states before their forward pass: qpos, qvel, ctrl drawn in range; with `active`,
    instance 0's cart sits 0.05 past the slider's upper end, still moving outwards."""
    k1, k2, k3 = jax.random.split(jax.random.key(3), 3)
    qpos = jax.random.uniform(k1, (N, 2), minval=-0.5, maxval=0.5)
    qvel = jax.random.normal(k2, (N, 2))
    if active:
        qpos, qvel = qpos.at[0, 0].set(1.05), qvel.at[0, 0].set(0.5)
    ctrl = jax.random.uniform(k3, (N, 1), minval=-3.0, maxval=3.0)

    def one(q, v, c):
        return env._data_at(q, v, forward=False).replace(ctrl=c)

    return jax.vmap(one)(qpos, qvel, ctrl)


@pytest.fixture(scope="module")
def outputs(env):
    """(ours flat, ours nested 2 x N/2 reshaped back, MJX's) forward of each batch."""
    m = env.mjx_model
    ours = jax.jit(jax.vmap(lambda d: forward(m, d)))
    nested = jax.jit(jax.vmap(jax.vmap(lambda d: forward(m, d))))
    theirs = jax.jit(jax.vmap(lambda d: mjx.forward(m, d)))
    split = lambda t: jax.tree_util.tree_map(lambda x: x.reshape((2, N // 2) + x.shape[1:]), t)
    merge = lambda t: jax.tree_util.tree_map(lambda x: x.reshape((N,) + x.shape[2:]), t)
    result = {}
    for active in (False, True):
        d = batch(env, active)
        result[active] = jax.device_get((ours(d), merge(nested(split(d))), theirs(d)))
    return result


def leaves(tree):
    return jax.tree_util.tree_leaves_with_path(tree)


def test_mixed_batch_runs_mjx_solver_bit_for_bit(outputs):
    ours, nested, theirs = outputs[True]
    assert np.abs(theirs.qfrc_constraint[0]).max() > 0  # the limit does act on instance 0
    for (path, a), (_, b), (_, c) in zip(leaves(ours), leaves(nested), leaves(theirs)):
        np.testing.assert_array_equal(a, c, err_msg=jax.tree_util.keystr(path))
        np.testing.assert_array_equal(b, c, err_msg=jax.tree_util.keystr(path))


def test_idle_batch_skips_the_solver(env, outputs):
    ours, nested, theirs = outputs[False]
    np.testing.assert_array_equal(ours.qacc, ours.qacc_smooth)
    np.testing.assert_array_equal(ours.qfrc_constraint, 0.0)
    np.testing.assert_array_equal(ours._impl.efc_force, 0.0)
    for (path, a), (_, b) in zip(leaves(ours), leaves(nested)):
        np.testing.assert_array_equal(a, b, err_msg=jax.tree_util.keystr(path))
    np.testing.assert_allclose(theirs.qacc, ours.qacc, rtol=1e-5, atol=1e-5)
    np.testing.assert_array_equal(theirs.qfrc_constraint, 0.0)

    model, data = env.mj_model, mujoco.MjData(env.mj_model)
    d = batch(env, False)
    for i in range(N):
        data.qpos[:], data.qvel[:], data.ctrl[:] = d.qpos[i], d.qvel[i], d.ctrl[i]
        mujoco.mj_forward(model, data)
        assert data.nefc == 0
        np.testing.assert_allclose(ours.qacc[i], data.qacc, rtol=1e-5, atol=1e-5)


def test_unbatched_call_matches_the_batch(env, outputs):
    d = jax.tree_util.tree_map(lambda x: x[0], batch(env, True))
    one = jax.device_get(jax.jit(lambda d: forward(env.mjx_model, d))(d))
    for (path, a), (_, b) in zip(leaves(one), leaves(outputs[True][2])):
        np.testing.assert_array_equal(a, b[0], err_msg=jax.tree_util.keystr(path))


def test_nested_vmap_branches_once_on_a_scalar(env):
    def conds(jaxpr):
        for eqn in jaxpr.eqns:
            if eqn.primitive.name == "cond":
                yield eqn
            for sub in jax.extend.core.jaxprs_in_params(eqn.params):
                yield from conds(sub)

    m = env.mjx_model
    d = jax.tree_util.tree_map(lambda x: x.reshape((2, N // 2) + x.shape[1:]), batch(env, False))
    jaxpr = jax.make_jaxpr(jax.vmap(jax.vmap(lambda d: forward(m, d))))(d).jaxpr
    predicates = [eqn.invars[0].aval.shape for eqn in conds(jaxpr)]
    assert predicates == [()]
