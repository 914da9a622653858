"""Shared machinery of the MJX (MuJoCo XLA) environments.

The MuJoCo model is compiled from MJCF once per environment object and moved to the
device once with ``mjx.put_model``; ``reset``/``step`` only build and advance ``mjx.Data``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from envs._mjx import mjx, mjx_forward, mjx_scan
from envs import active_set_solver
from envs.types import Env


class MjxEnv(Env):
    """Base of MJX environments with one motor per action component.

    One environment step holds ``ctrl`` fixed for ``frame_skip`` MuJoCo steps, so
    ``dt = frame_skip * timestep``, exactly like Gymnasium's ``MujocoEnv.do_simulation``.
    """

    def __init__(
        self,
        name: str,
        xml: str,
        frame_skip: int,
        observation_size: int,
        action_low: np.ndarray,
        action_high: np.ndarray,
        max_episode_steps: int,
    ):
        self.mj_model = mujoco.MjModel.from_xml_string(xml)
        # MuJoCo's sparse inertia: the same M, factored by MJX in plain array operations
        # rather than a batched LAPACK Cholesky, which a GPU runs as several launches per
        # call (BENCHMARKS.md: an H100 steps 8 pendulums in 0.42 ms instead of 0.72 ms).
        self.mj_model.opt.jacobian = mujoco.mjtJacobian.mjJAC_SPARSE
        self.mjx_model = mjx.put_model(self.mj_model)
        self._frame_skip = int(frame_skip)
        super().__init__(
            name,
            observation_size,
            action_low,
            action_high,
            max_episode_steps,
            dt=self.mj_model.opt.timestep * self._frame_skip,
        )

    def _data_at(self, qpos: jax.Array, qvel: jax.Array, forward: bool = True) -> mjx.Data:
        """``mjx.Data`` at qpos (nq,), qvel (nv,) with ctrl 0.

        With ``forward`` the derived fields come from a forward pass, as after Gymnasium's
        ``set_state`` (which calls ``mj_forward``), for observations that read site positions
        or constraint forces. Without it they stay zero until the first step recomputes them:
        cheaper to compile where the observation is (qpos, qvel) alone.
        """
        data = mjx.make_data(self.mjx_model)
        dtype = data.qpos.dtype
        data = data.replace(qpos=qpos.astype(dtype), qvel=qvel.astype(dtype))
        return active_set_solver.forward(self.mjx_model, data) if forward else data

    def _rk4(self, d0: mjx.Data) -> mjx.Data:
        """One MuJoCo RK4 step, numerically ``mjx.step``'s with integrator RK4 and
        `envs.active_set_solver.forward` as its forward (which solves the constraint problem
        of these small models exactly, without MJX's solver iterations).

        ``mjx.step`` traces ``mjx.forward`` four times (once, then inside a scan unrolled 3x);
        here the four stages k_s, s = 0..3, run in one scan with a single traced forward:

            q_s = q_0 (+) a_s dt k_{s-1}^qvel,   v_s = v_0 + a_s dt k_{s-1}^qacc,
            (a_s) = (0, 1/2, 1/2, 1),   t_s = t_0 + a_s dt
            v_1 = v_0 + dt sum_s b_s qacc_s,   q_1 = q_0 (+) dt sum_s b_s v_s,
            (b_s) = (1/6, 1/3, 1/3, 1/6)

        Stage 0 adds exact zeros, so every rounding matches MJX's own RK4. Compiling one
        forward instead of four cuts the environment's compile time about fourfold.
        """
        m = self.mjx_model
        dt = m.opt.timestep
        integrate = lambda *args: mjx_forward._integrate_pos(*args, dt=dt)
        a = jnp.asarray([0.0, 0.5, 0.5, 1.0], d0.qpos.dtype)
        b = jnp.asarray(mjx_forward._RK4_B, d0.qpos.dtype)

        def stage(carry, x):
            qvel_sum, qacc_sum, act_dot_sum, d = carry
            a_s, b_s = x
            kqpos = mjx_scan.flat(m, integrate, "jqv", "q", m.jnt_type, d0.qpos, a_s * d.qvel)
            d = d.replace(qpos=kqpos, qvel=d0.qvel + a_s * d.qacc * dt,
                          act=d0.act + a_s * d.act_dot * dt, time=d0.time + a_s * dt)
            d = active_set_solver.forward(m, d)
            return (qvel_sum + b_s * d.qvel, qacc_sum + b_s * d.qacc,
                    act_dot_sum + b_s * d.act_dot, d), None

        zeros = (jnp.zeros_like(d0.qvel), jnp.zeros_like(d0.qvel), jnp.zeros_like(d0.act))
        (qvel, qacc, act_dot, d1), _ = jax.lax.scan(stage, zeros + (d0,), (a, b))
        d = d1.replace(qpos=d0.qpos, qvel=d0.qvel, act=d0.act, time=d0.time)
        return mjx_forward._advance(m, d, act_dot, qacc, qvel)

    def _simulate(self, data: mjx.Data, ctrl: jax.Array) -> mjx.Data:
        """Advance ``frame_skip`` MuJoCo steps with ``ctrl`` (nu,) held constant.

        After the call, kinematic quantities such as ``site_xpos`` and ``qfrc_constraint`` are
        those of MuJoCo's last internal evaluation, as in C MuJoCo's ``mj_step``.
        """
        data = data.replace(ctrl=ctrl.astype(data.ctrl.dtype))
        if self.mj_model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:
            physics_step = self._rk4
        else:
            physics_step = lambda d: mjx.step(self.mjx_model, d)
        return jax.lax.fori_loop(0, self._frame_skip, lambda _, d: physics_step(d), data)

    def _uniform_noise(self, key: jax.Array, size: int, scale: float) -> jax.Array:
        """(size,) draws of U(-scale, scale) in the model's float dtype."""
        dtype = self.mjx_model.qpos0.dtype
        return jax.random.uniform(key, (size,), dtype, minval=-scale, maxval=scale)

