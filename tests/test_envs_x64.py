"""With ``jax_enable_x64`` our environments agree with Gymnasium's to float64 rounding.

Runs inside the ``jax.enable_x64(True)`` context manager (jit caches are keyed on it, so
x64 does not leak into other tests) on the environments with distinct physics:
InvertedPendulum-v5 (v4 and Bullet share its model), InvertedDoublePendulum-v5 and
Pendulum-v1, with the closed-loop inputs of tests/_env_reference.py.

Measured max |Δ(q, q̇)| between our float64 physics state and Gymnasium's over the whole
episode (CPU, seed 0): 1.1e-15 (InvertedPendulum-v5, 253 steps), 5.1e-15
(InvertedDoublePendulum-v5, 254 steps), 3.9e-13 (Pendulum-v1, 200 steps; θ is
unnormalised and grows to tens of radians); compare 1e-7 .. 1e-5 in float32.
The MJX environments' lean RK4 stages (`envs.mjx_env.MjxEnv.lean_stages`, a GPU's default)
are checked too: 1.1e-15 and 8.9e-15. Asserted: 1e-10 (float64's ulp of states up to 12,
1.8e-15, times an amplification over the episode that any closed loop here would need to exceed
5e4 to reach it; the largest above is 220).  Observations are float32 by contract, so they agree
to the float32 rounding of the value: one ulp, 2^-23 relative (asserted 1e-6 relative, plus
1e-6 absolute for values near 0).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import envs
from tests import _env_reference as ref


@pytest.mark.parametrize("name, lean", [
    ("InvertedPendulum-v5", False), ("InvertedPendulum-v5", True),
    ("InvertedDoublePendulum-v5", False), ("InvertedDoublePendulum-v5", True),
    ("Pendulum-v1", None)])
def test_float64_matches_gymnasium_to_rounding(name, lean):
    with jax.enable_x64(True):
        env = envs.make(name)
        if lean is not None:
            env.lean_stages = lean
        gain, on, noise = ref.inputs(env)
        gain, noise = np.float64(gain), np.float64(noise)
        s0, states = ref.make_rollout(env)(jax.random.key(0), jnp.int32(0), gain, on, noise)
        ours = np.asarray(ref.physics_state(states.data))
        assert ours.dtype == np.float64
        theirs = ref.gym_rollout(name, s0, gain, on, noise, dtype=np.float64)
    n = len(theirs["reward"])
    state_err = np.abs(ours[:n] - theirs["state"]).max()
    print(f"{name}: float64 max |d(q, qdot)| = {state_err:.3g} over {n} steps")
    assert state_err <= 1e-10
    np.testing.assert_allclose(np.asarray(states.obs[:n]), theirs["obs"], rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(np.asarray(states.terminated[:n]), theirs["terminated"])
    np.testing.assert_array_equal(np.asarray(states.truncated[:n]), theirs["truncated"])
