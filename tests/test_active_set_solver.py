"""`envs.active_set_solver` against C MuJoCo's `mj_forward` / `mj_step` and MJX's own solver.

States of both MJX pendulums with joints drawn beyond their limits (slider range [-1, 1],
InvertedPendulum's hinge [-90, 90] degrees), random velocities and controls, so that each
model's constraint rows are active alone, together and not at all. Asserted:
  float64: qacc and qfrc_constraint equal C MuJoCo's to 1e-10 relative (measured: at most
      2e-14 and 1e-13): the solve is exact, not iterative;
  float32: one forward pass (no horizon), within 4 nv kappa 2^-24 relative of C MuJoCo's
      (kappa: the largest condition number of the mass matrix over the drawn states, 32 and 190;
      a solve with M turns relative rounding of order nv u in M and the forces into kappa times
      that) and twice that of MJX's own float32 solver (measured: at most 7e-6 and 5e-6, bounds
      1.5e-5 and 1.4e-4 against C);
  a float64 rollout pushed into the limits (forces on most steps) follows C MuJoCo's
      `mj_step` to 1e-9 (measured 1e-10 and 6e-12, from 2e-15 before the first impact);
  a model the enumeration does not cover (friction loss) gets MJX's solver, bit for bit;
  vmapped, the forward pass has no loop or branch left (MJX's solver: a while loop);
  `cholesky_solve` equals `numpy.linalg.solve`.
"""

from __future__ import annotations

import jax
import jax.extend.core
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

import envs
from envs import active_set_solver
from envs._mjx import mjx
from envs.mjx_env import MjxEnv

N = 64
NAMES = ["InvertedPendulum-v5", "InvertedDoublePendulum-v5"]


def draw(env, key, n=N):
    """(qpos (n, nq), qvel (n, nv), ctrl (n, nu)) float64 numpy: the slider in [-1.5, 1.5],
    hinges in [-2, 2] rad (beyond +-pi/2), velocities ~ N(0, 2^2), ctrl within its range."""
    nq, nu = env.mj_model.nq, env.mj_model.nu
    k1, k2, k3 = jax.random.split(jax.random.key(key), 3)
    scale = np.array([1.5] + [2.0] * (nq - 1))
    qpos = scale * np.asarray(jax.random.uniform(k1, (n, nq), minval=-1.0, maxval=1.0))
    qvel = 2.0 * np.asarray(jax.random.normal(k2, (n, nq)))
    ctrl = np.asarray(jax.random.uniform(k3, (n, nu), minval=-1.0, maxval=1.0))
    return np.float64(qpos), np.float64(qvel), np.float64(ctrl)


def forward_batch(env, fn, qpos, qvel, ctrl):
    """`fn(m, d)` (a forward pass) vmapped over the states, as numpy."""
    m = env.mjx_model
    dtype = m.qpos0.dtype

    def one(q, v, c):
        return fn(m, env._data_at(q, v, forward=False).replace(ctrl=c.astype(dtype)))

    return jax.device_get(jax.jit(jax.vmap(one))(qpos.astype(dtype), qvel.astype(dtype), ctrl))


def c_forward(env, qpos, qvel, ctrl):
    """C MuJoCo's (qacc, qfrc_constraint, number of constraint rows) per state."""
    model, data = env.mj_model, mujoco.MjData(env.mj_model)
    out = []
    for q, v, c in zip(qpos, qvel, ctrl):
        data.qpos[:], data.qvel[:], data.ctrl[:] = q, v, c
        mujoco.mj_forward(model, data)
        out.append((data.qacc.copy(), data.qfrc_constraint.copy(), data.nefc))
    return [np.array(x) for x in zip(*out)]


def mass_matrix_condition(env, qpos) -> float:
    """The largest condition number of C MuJoCo's mass matrix M(q) over the states `qpos`."""
    model, data = env.mj_model, mujoco.MjData(env.mj_model)
    worst = 1.0
    for q in qpos:
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        full = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, full)
        worst = max(worst, float(np.linalg.cond(full)))
    return worst


def relative(a, b):
    return float(np.max(np.abs(a - b) / (1.0 + np.abs(b))))


@pytest.mark.parametrize("name", NAMES)
def test_float64_equals_c_mujoco(name):
    """float64, one forward pass: 2^-52 times the mass matrix's condition number (<= 190) is
    4e-14, so 1e-10 relative holds with room for a larger chain of roundings."""
    with jax.enable_x64(True):
        env = envs.make(name)
        states = draw(env, 0)
        ours = forward_batch(env, active_set_solver.forward, *states)
    qacc, qfrc, nefc = c_forward(env, *states)
    # every pattern of active rows occurs: none, each, and (pendulum) both
    assert {0, 1} <= set(nefc.tolist())
    if name == "InvertedPendulum-v5":
        assert 2 in set(nefc.tolist())
    print(f"{name}: float64 qacc {relative(ours.qacc, qacc):.2g}, "
          f"qfrc_constraint {relative(ours.qfrc_constraint, qfrc):.2g}")
    assert relative(ours.qacc, qacc) <= 1e-10
    assert relative(ours.qfrc_constraint, qfrc) <= 1e-10


@pytest.mark.parametrize("name", NAMES)
def test_float32_within_rounding_of_c_mujoco_and_mjx(name):
    """float32 precision times the mass matrix's condition number (module docstring)."""
    env = envs.make(name)
    states = draw(env, 1)
    ours = forward_batch(env, active_set_solver.forward, *states)
    theirs = forward_batch(env, mjx.forward, *states)
    qacc, qfrc, nefc = c_forward(env, *states)
    assert np.mean(nefc > 0) > 0.25
    bound = 4 * env.mj_model.nv * mass_matrix_condition(env, states[0]) * 2.0 ** -24
    for field, c_value in (("qacc", qacc), ("qfrc_constraint", qfrc)):
        ours_f, mjx_f = getattr(ours, field), getattr(theirs, field)
        print(f"{name}: float32 {field} vs C {relative(ours_f, c_value):.2g}, "
              f"vs MJX {relative(ours_f, mjx_f):.2g}; MJX vs C {relative(mjx_f, c_value):.2g}")
        assert relative(ours_f, c_value) <= bound, bound
        assert relative(ours_f, mjx_f) <= 2 * bound, bound


@pytest.mark.parametrize("name", NAMES)
def test_rollout_into_the_limits_follows_c_mujoco(name):
    """60 environment steps of full actions, 25 one way then 15 back and so on, from the reset
    state, float64, against C MuJoCo's mj_step with the same controls. Longer, the double
    pendulum's chaos shows: its gap grows about 10x per 10 steps (1e-8 at 90 steps). Bound 1e-9:
    float64's 2.2e-16 amplified 10x per 10 steps over 60 steps is 2.2e-10."""
    steps = 60
    with jax.enable_x64(True):
        env = envs.make(name)
        push = np.where(np.arange(steps) % 40 < 25, 1.0, -1.0)[:, None] * env.action_high

        def run(key):
            def step(state, action):
                state = env.step(state, action)
                return state, (state.data.qpos, state.data.qvel, state.data.qfrc_constraint)

            state = env.reset(key)
            return (state.data.qpos, state.data.qvel), jax.lax.scan(step, state, push)[1]

        (qpos0, qvel0), (qpos, qvel, qfrc) = jax.device_get(jax.jit(run)(jax.random.key(2)))
    model, data = env.mj_model, mujoco.MjData(env.mj_model)
    data.qpos[:], data.qvel[:] = qpos0, qvel0
    frame_skip = round(env.dt / model.opt.timestep)
    theirs = []
    for action in push:
        data.ctrl[:] = action
        mujoco.mj_step(model, data, nstep=frame_skip)
        theirs.append(np.concatenate([data.qpos, data.qvel]))
    err = np.abs(np.concatenate([qpos, qvel], axis=1) - np.array(theirs)).max()
    print(f"{name}: float64 rollout max |d(q, qdot)| {err:.2g}")
    assert np.mean(np.abs(qfrc).max(axis=1) > 0) > 0.5  # a limit acts on most steps
    assert err <= 1e-9


FRICTION_XML = """
<mujoco>
  <option integrator="RK4" timestep="0.02"/>
  <worldbody>
    <body>
      <joint name="slider" type="slide" axis="1 0 0" range="-1 1" frictionloss="0.5"/>
      <geom type="box" size="0.1 0.1 0.1" contype="0"/>
    </body>
  </worldbody>
  <actuator><motor joint="slider"/></actuator>
</mujoco>
"""


def test_model_with_friction_loss_gets_mjx_solver():
    env = MjxEnv("friction", FRICTION_XML, 1, 2, np.array([-1.0]), np.array([1.0]), 10)
    states = (np.array([[0.3], [1.2]]), np.array([[0.5], [1.0]]), np.array([[0.2], [-0.4]]))
    ours = forward_batch(env, active_set_solver.forward, *states)
    assert not active_set_solver.applies(env._data_at(np.zeros(1), np.zeros(1), False))
    theirs = forward_batch(env, mjx.forward, *states)
    assert np.abs(theirs.qfrc_constraint).min() > 0
    for (path, a), (_, b) in zip(jax.tree_util.tree_leaves_with_path(ours),
                                 jax.tree_util.tree_leaves_with_path(theirs)):
        np.testing.assert_array_equal(a, b, err_msg=jax.tree_util.keystr(path))


def primitives(jaxpr):
    for eqn in jaxpr.eqns:
        yield eqn.primitive.name
        for sub in jax.extend.core.jaxprs_in_params(eqn.params):
            yield from primitives(sub)


@pytest.mark.parametrize("name", NAMES)
def test_vmapped_forward_has_no_loop_or_branch(name):
    env = envs.make(name)
    m = env.mjx_model
    d = jax.vmap(lambda q: env._data_at(q, q, forward=False))(jnp.zeros((4, env.mj_model.nq)))
    used = lambda fn: set(primitives(jax.make_jaxpr(jax.vmap(lambda d: fn(m, d)))(d).jaxpr))
    ours, theirs = used(active_set_solver.forward), used(mjx.forward)
    assert "while" in theirs
    assert not ours & {"while", "cond", "scan"}


@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_cholesky_solve(n):
    """float64; h = a a^T + n I has condition number below 1e3 here, so 1e-10 relative is far
    above 2^-52 times it."""
    rng = np.random.default_rng(n)
    a = rng.normal(size=(7, n, n))
    h, b = a @ a.transpose(0, 2, 1) + n * np.eye(n), rng.normal(size=(7, n))
    with jax.enable_x64(True):
        x = active_set_solver.cholesky_solve(
            [[jnp.asarray(h[:, i, j]) for j in range(n)] for i in range(n)],
            [jnp.asarray(b[:, i]) for i in range(n)])
    np.testing.assert_allclose(np.stack(x, axis=-1), np.linalg.solve(h, b[..., None])[..., 0],
                               rtol=1e-10)

