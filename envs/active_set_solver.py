"""MJX forward dynamics with a small model's constraint problem solved exactly, without iterations.

MuJoCo's constraint solver finds the joint acceleration a that minimises

    f(a) = 1/2 (a - a0)^T M (a - a0) + sum_i s_i(J_i a - r_i),

with a0 = qacc_smooth, M the joint-space inertia (nv, nv), and per constraint row i its Jacobian
row J_i (nv,), reference acceleration r_i (efc_aref) and stiffness D_i (efc_D). An equality row
costs s_i(x) = 1/2 D_i x^2 always; a joint-limit or pyramidal-contact row costs it only while
pushed, x < 0 (then it is "active"). Friction-loss rows and elliptic cones cost otherwise.

With quadratic rows only, f restricted to a set S of active rows is a quadratic, minimised by

    (M + J_S^T D_S J_S) a_S = M a0 + J_S^T D_S r_S.                                  (1)

f is convex and continuously differentiable, so its minimiser a* is a_S for the set S active at
a*, and f(a_S) >= f(a*) for every other S:

    a* = argmin_S f(a_S),  S = the equality rows plus any subset of the n other rows.   (2)

`solve` evaluates (1) for all 2^n sets at once and takes (2): a fixed sequence of small dense
operations, each (1) an nv x nv Cholesky written out element by element, which XLA fuses into
a few kernels. MJX's Newton solver reaches the same a* (to its tolerance) through a while
loop whose every iteration factors the Hessian with a batched LAPACK Cholesky and runs a line
search; on a GPU those sequential launches, not arithmetic, set a pendulum step's cost. The
pendulum models have n = 2 (InvertedPendulum: slider and hinge limits) and n = 1
(InvertedDoublePendulum: the slider limit); `forward` uses MJX's solver where the enumeration
does not apply (friction loss, contacts, or more than `MAX_ROWS` inequality rows).

Outputs follow MJX's solver: qacc = a*, efc_force = -D (J a* - r) on active rows and 0 on the
others, qfrc_constraint = J^T efc_force. They agree with MJX's solver and with C MuJoCo's
`mj_forward` to float32 rounding (`tests/test_active_set_solver.py`). No reverse-mode
derivative is meant to pass through the selection (2); nothing here differentiates the
simulator.
"""

from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp

from envs._mjx import mjx, mjx_forward, mjx_sensor, mjx_solver, mjx_support

MAX_ROWS = 4
"""Most inequality rows enumerated: (1) is solved for 2^MAX_ROWS = 16 sets at most."""


def applies(d: mjx.Data) -> bool:
    """Whether every row of ``d``'s constraint problem has a quadratic cost and at most
    `MAX_ROWS` of them are inequalities (static: row counts are fixed by the model)."""
    impl = d._impl
    return impl.nf == 0 and impl.ncon == 0 and impl.nefc - impl.ne <= MAX_ROWS


def forward(m: mjx.Model, d: mjx.Data) -> mjx.Data:
    """``mjx.forward(m, d)`` (MJX 3.17's sequence of stages) with `solve` as its constraint
    solver where `applies`, MJX's own otherwise."""
    d = mjx_forward.fwd_position(m, d)
    d = mjx_sensor.sensor_pos(m, d)
    d = mjx_forward.fwd_velocity(m, d)
    d = mjx_sensor.sensor_vel(m, d)
    d = mjx_forward.fwd_actuation(m, d)
    d = mjx_forward.fwd_acceleration(m, d)
    if d._impl.efc_J.size == 0:
        return d.replace(qacc=d.qacc_smooth)
    d = solve(m, d) if applies(d) else mjx_solver.solve(m, d)
    return mjx_sensor.sensor_acc(m, d)


def cholesky_solve(h: list[list[jax.Array]], b: list[jax.Array]) -> list[jax.Array]:
    """x with h x = b for a small symmetric positive definite h: the Cholesky factor
    h = L L^T and the two triangular solves written out per element. Each entry of h (n x n
    nested lists) and b (n) is an array of one shape, e.g. () or a batch (B,) under vmap."""
    n = len(b)
    low = [[None] * n for _ in range(n)]
    for j in range(n):
        low[j][j] = jnp.sqrt(h[j][j] - sum(low[j][k] ** 2 for k in range(j)))
        for i in range(j + 1, n):
            low[i][j] = (h[i][j] - sum(low[i][k] * low[j][k] for k in range(j))) / low[j][j]
    y = []
    for i in range(n):
        y.append((b[i] - sum(low[i][k] * y[k] for k in range(i))) / low[i][i])
    x = [None] * n
    for i in reversed(range(n)):
        x[i] = (y[i] - sum(low[k][i] * x[k] for k in range(i + 1, n))) / low[i][i]
    return x


def solve(m: mjx.Model, d: mjx.Data) -> mjx.Data:
    """The constraint solver's result for one instance by (1)-(2); see the module docstring.

    Every quantity is written out per scalar entry (efc_J (nefc, nv), efc_aref and efc_D
    (nefc,), M (nv, nv)), so that under `vmap` the whole solve is elementwise arithmetic on
    (B,) arrays, which XLA fuses into one loop on a CPU and a few kernels on a GPU. The sets
    S are enumerated in Python; the best a_S so far is kept with selects.
    """
    impl = d._impl
    nv, nefc, ne = d.qacc.shape[0], impl.nefc, impl.ne
    full = mjx_support.full_m(m, d)  # M, (nv, nv)
    jac = [[impl.efc_J[r, i] for i in range(nv)] for r in range(nefc)]
    aref = [impl.efc_aref[r] for r in range(nefc)]
    stiff = [impl.efc_D[r] for r in range(nefc)]
    mass = [[full[i, j] for j in range(nv)] for i in range(nv)]
    a0 = [d.qacc_smooth[i] for i in range(nv)]
    f0 = [d.qfrc_smooth[i] for i in range(nv)]

    best = None
    for free in itertools.product((False, True), repeat=nefc - ne):
        rows = [r for r, on in enumerate((True,) * ne + free) if on]
        h = [[mass[i][j] + sum(stiff[r] * jac[r][i] * jac[r][j] for r in rows) for j in range(nv)]
             for i in range(nv)]
        b = [f0[i] + sum(stiff[r] * aref[r] * jac[r][i] for r in rows) for i in range(nv)]
        qacc = cholesky_solve(h, b)  # a_S of (1)
        jaref = [sum(jac[r][i] * qacc[i] for i in range(nv)) - aref[r] for r in range(nefc)]
        active = [jnp.bool_(r < ne) | (jaref[r] < 0) for r in range(nefc)]
        cost = 0.5 * sum((sum(mass[i][j] * qacc[j] for j in range(nv)) - f0[i]) * (qacc[i] - a0[i])
                         for i in range(nv))  # f(a_S): MJX's Gauss term, then the rows'
        cost += 0.5 * sum(jnp.where(active[r], stiff[r] * jaref[r] ** 2, 0.0) for r in range(nefc))
        force = [jnp.where(active[r], -stiff[r] * jaref[r], 0.0) for r in range(nefc)]
        candidate = (cost, qacc, force)
        if best is None:
            best = candidate
        else:  # (2), ties to the earlier set
            better = cost < best[0]
            best = jax.tree_util.tree_map(lambda new, old: jnp.where(better, new, old),
                                          candidate, best)
    _, qacc, force = best
    return d.tree_replace({
        "qacc": jnp.stack(qacc),
        "qfrc_constraint": jnp.stack([sum(jac[r][i] * force[r] for r in range(nefc))
                                      for i in range(nv)]),
        "_impl.efc_force": jnp.stack(force),
    })
