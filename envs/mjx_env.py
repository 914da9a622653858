"""Shared machinery of the MJX (MuJoCo XLA) environments.

The MuJoCo model is compiled from MJCF once per environment object and moved to the
device once with ``mjx.put_model``; ``reset``/``step`` only build and advance ``mjx.Data``.
"""

from __future__ import annotations

from typing import Optional

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

    simulates_mujoco = True

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
        # call (measured in commit 9b0b254: an H100 stepped 8 pendulums in 0.42 ms, not 0.72 ms).
        self.mj_model.opt.jacobian = mujoco.mjtJacobian.mjJAC_SPARSE
        self.mjx_model = mjx.put_model(self.mj_model)
        self._frame_skip = int(frame_skip)
        self.lean_stages: Optional[bool] = None
        """Whether RK4 steps take `_rk4_lean` (True) or `_rk4` (False); None: lean unless the
        default backend is a CPU. Read when a step is traced."""
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

    def _stage_input(self, d: mjx.Data, start, k, a_s) -> mjx.Data:
        """``d`` at the state of one RK4 stage (see `_rk4`): ``start`` = (qpos, qvel, act, time,
        qacc_warmstart) of the MuJoCo step, ``k`` = (qvel, qacc, act_dot) of the previous stage."""
        m = self.mjx_model
        dt = m.opt.timestep
        qpos, qvel, act, time, warmstart = start
        k_qvel, k_qacc, k_act_dot = k
        integrate = lambda *args: mjx_forward._integrate_pos(*args, dt=dt)
        return d.replace(
            qpos=mjx_scan.flat(m, integrate, "jqv", "q", m.jnt_type, qpos, a_s * k_qvel),
            qvel=qvel + a_s * k_qacc * dt, act=act + a_s * k_act_dot * dt, time=time + a_s * dt,
            qacc_warmstart=warmstart)

    def _step_end(self, last: mjx.Data, start, sums) -> mjx.Data:
        """The MuJoCo step's result: ``last`` (its fourth stage's forward) advanced from
        ``start`` by the stages' weighted sums (qvel, qacc, act_dot), as MJX's RK4 does."""
        qpos, qvel, act, time, _ = start
        sum_qvel, sum_qacc, sum_act_dot = sums
        return mjx_forward._advance(
            self.mjx_model, last.replace(qpos=qpos, qvel=qvel, act=act, time=time),
            sum_act_dot, sum_qacc, sum_qvel)

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
        start = (d0.qpos, d0.qvel, d0.act, d0.time, d0.qacc_warmstart)

        def stage(carry, x):
            sums, d = carry
            a_s, b_s = x
            d = active_set_solver.forward(
                m, self._stage_input(d, start, (d.qvel, d.qacc, d.act_dot), a_s))
            return (_weighted_add(sums, b_s, d), d), None

        a, b, _ = _rk4_weights(d0, 1)
        (sums, last), _ = jax.lax.scan(stage, (_zero_sums(d0), d0), (a, b))
        return self._step_end(last, start, sums)

    def _rk4_lean(self, data: mjx.Data) -> mjx.Data:
        """``frame_skip`` RK4 steps as `_rk4` computes them, with every stage but the last
        carrying only the state it hands on: (start, k, sums) of `_stage_input` and
        `_step_end`, never a whole ``mjx.Data``. XLA then neither keeps nor copies what those
        stages compute for no later stage (camera and light frames, geom and site poses,
        constraint forces, sensors). Only the last stage's forward, called again after the
        scan, fills every field of the result; a jitted stage function gives both calls one
        trace (`fast`'s chunk in this form traces in 1.45-1.52 s instead of 1.94-1.95 s on 2
        CPU cores, 3 traces each). One scan runs the 4 x frame_skip - 1 lean stages; a MuJoCo
        step ends after every fourth.

        On an H100 (`benchmarks/results/evaluation_cost-h100.json`) a 1,000-step evaluation
        of 5 InvertedPendulum-v5 episodes takes 0.38 s instead of 0.55 s, of 256 x 5 episodes
        0.45 s instead of 0.61 s, and the training chunk's environment steps 30 % less kernel
        time. On a CPU it is slower (0.138 against 0.105 ms per step of 8 instances). Before
        the forward's two calls shared a trace, it cost 4 s more trace and compile of the
        default preset on a CPU, and on an H100 about 2 s of a cold `fast` run's 19 s compile
        while saving 0.25 s of its 1.95 s training (ad hoc, one cold and warm run each;
        `compile_options-levels-h100.json` has the lean runs). Since, an H100 compiles `fast`
        as fast either way (3 alternated cold runs: 16.4-19.4 s lean, 15.4-20.2 s not) and
        trains it to solved in 1.65-1.74 s lean against 1.94-2.21 s (ad hoc, 2026-11-27).
        """
        m = self.mjx_model
        a, b, ends = _rk4_weights(data, self._frame_skip)
        zeros = _zero_sums(data)

        stage_forward = jax.jit(lambda d, start, k, a_s: active_set_solver.forward(
            m, self._stage_input(d, start, k, a_s)))

        def stage(carry, x):
            start, k, sums = carry
            a_s, b_s, end = x
            d = stage_forward(data, start, k, a_s)
            sums = _weighted_add(sums, b_s, d)
            nxt = self._step_end(d, start, sums)
            nxt = (nxt.qpos, nxt.qvel, nxt.act, nxt.time, nxt.qacc_warmstart)
            start, sums = jax.tree_util.tree_map(
                lambda new, old: jnp.where(end, new, old), (nxt, zeros), (start, sums))
            return (start, (d.qvel, d.qacc, d.act_dot), sums), None

        start = (data.qpos, data.qvel, data.act, data.time, data.qacc_warmstart)
        (start, k, sums), _ = jax.lax.scan(
            stage, (start, zeros, zeros), (a[:-1], b[:-1], ends[:-1]))
        last = stage_forward(data, start, k, a[-1])
        return self._step_end(last, start, _weighted_add(sums, b[-1], last))

    def _simulate(self, data: mjx.Data, ctrl: jax.Array) -> mjx.Data:
        """Advance ``frame_skip`` MuJoCo steps with ``ctrl`` (nu,) held constant.

        After the call, kinematic quantities such as ``site_xpos`` and ``qfrc_constraint`` are
        those of MuJoCo's last internal evaluation, as in C MuJoCo's ``mj_step``. RK4 models
        take `_rk4_lean` where `lean_stages` says so, else `_rk4` per step; both give the
        same result to float rounding.
        """
        data = data.replace(ctrl=ctrl.astype(data.ctrl.dtype))
        if self.mj_model.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4:
            physics_step = lambda d: mjx.step(self.mjx_model, d)
        elif self._uses_lean_stages():
            return self._rk4_lean(data)
        else:
            physics_step = self._rk4
        return jax.lax.fori_loop(0, self._frame_skip, lambda _, d: physics_step(d), data)

    def _uses_lean_stages(self) -> bool:
        return jax.default_backend() != "cpu" if self.lean_stages is None else self.lean_stages

    def _uniform_noise(self, key: jax.Array, size: int, scale: float) -> jax.Array:
        """(size,) draws of U(-scale, scale) in the model's float dtype."""
        dtype = self.mjx_model.qpos0.dtype
        return jax.random.uniform(key, (size,), dtype, minval=-scale, maxval=scale)


def _rk4_weights(d: mjx.Data, steps: int):
    """(a_s, b_s, whether the stage ends a step) of `steps` RK4 steps' 4 * steps stages."""
    dtype = d.qpos.dtype
    return (jnp.tile(jnp.asarray([0.0, 0.5, 0.5, 1.0], dtype), steps),
            jnp.tile(jnp.asarray(mjx_forward._RK4_B, dtype), steps),
            jnp.tile(jnp.asarray([False, False, False, True]), steps))


def _zero_sums(d: mjx.Data):
    """Zero (qvel, qacc, act_dot) sums of the RK4 stages, batched as ``d`` is under ``vmap``
    (selected from ``d``'s arrays, not made by ``zeros_like``): a scan whose carry starts
    unbatched and comes out batched has its body batched twice, once to find that out, and
    the stages' body is most of an environment step's trace (`fast`'s chunk on 2 CPU cores,
    3 traces each: 1.55-1.62 s to trace before, 1.29-1.32 s after)."""
    return tuple(jnp.where(False, x, jnp.zeros_like(x)) for x in (d.qvel, d.qvel, d.act))


def _weighted_add(sums, b_s, d: mjx.Data):
    """sums + b_s (qvel, qacc, act_dot) of stage ``d``."""
    return tuple(total + b_s * x for total, x in zip(sums, (d.qvel, d.qacc, d.act_dot)))
