"""Our environments against Gymnasium's (C MuJoCo / NumPy), plus reset, bad input, errors.

Every environment compiles exactly one function here: a jitted reset + ``lax.scan``
rollout of T = 300 closed-loop steps (see tests/_env_reference.py), reused by all tests.

Measured float32 agreement with Gymnasium (seed 0, CPU), max |Δobs| over the first 100
steps / the whole episode: 5.8e-7 / 8.2e-7 (InvertedPendulum-v5 and -v4, 253 steps),
5.7e-7 / 8.1e-7 (Bullet), 3.1e-6 / 3.1e-6 (InvertedDoublePendulum-v5, 254 steps),
1.6e-6 / 1.0e-5 (Pendulum-v1, 200 steps, float32 vs float64 arithmetic); the
terminated/truncated flags agree exactly.  Asserted, from precision × horizon: observations
to 1e-3 over the episode: float32's rounding of states up to 12 in magnitude (one ulp 9.5e-7)
times the closed loop's amplification over an episode, which the float64 comparison
(test_envs_x64.py) puts at <= 220 ulps (Pendulum-v1: 3.9e-13 from ulps of 1.8e-15; the
others <= 4): 2.1e-4, so 1e-3 leaves a factor of 5. Rewards to 10 times the observations'
largest difference plus 4 float32 ulps of the largest reward: each reward is a function of the
state with Lipschitz constant below 10 (Pendulum-v1: 2π + 0.2 · 8 + 0.002 · 2;
InvertedDoublePendulum-v5: 2 |y - 2| · 1.2 + 0.01 |v|; the others constant). Identical flags.
The float64 figures are in tests/test_envs_x64.py.
"""

from __future__ import annotations

import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import envs
from tests import _env_reference as ref

NAMES = tuple(envs.registry.SPECS)
"""Our own environments (MuJoCo Playground's, also registered, are tests/test_playground.py's)."""


@pytest.fixture(scope="module")
def compiled():
    """name -> (env, jitted rollout); each rollout compiles on first use only."""
    made = {name: envs.make(name) for name in NAMES}
    return {name: (env, ref.make_rollout(env)) for name, env in made.items()}


def run(compiled, name, key=0, step_count0=0, seed=0, noise=None):
    env, rollout = compiled[name]
    gain, on, default_noise = ref.inputs(env, seed)
    noise = default_noise if noise is None else noise
    s0, states = rollout(jax.random.key(key), jnp.int32(step_count0), gain, on, noise)
    return env, (gain, on, noise), s0, jax.tree_util.tree_map(np.asarray, states)


@pytest.mark.parametrize("name", NAMES)
def test_matches_gymnasium(compiled, name):
    env, (gain, on, noise), s0, states = run(compiled, name)
    theirs = ref.gym_rollout(name, s0, gain, on, noise)
    n = len(theirs["reward"])
    # one float32 rounding of values up to 8: at most 9.5e-7
    np.testing.assert_allclose(np.asarray(s0.obs), theirs["obs0"], atol=1e-6)
    err = np.abs(states.obs[:n] - theirs["obs"]).max(axis=1)
    print(f"{name}: float32 max |d obs| 100 steps {err[:100].max():.2g}, {n} steps {err.max():.2g}")
    assert err.max() <= 1e-3, err.max()
    reward_err = np.abs(states.reward[:n] - theirs["reward"]).max()
    ulp = np.spacing(np.float32(np.abs(theirs["reward"]).max()))
    assert reward_err <= 10 * err.max() + 4 * ulp, (reward_err, err.max())
    np.testing.assert_array_equal(states.terminated[:n], theirs["terminated"])
    np.testing.assert_array_equal(states.truncated[:n], theirs["truncated"])
    if name == "Pendulum-v1":
        assert n == env.max_episode_steps and theirs["truncated"][-1]
    else:  # survives the stabilised phase, then terminates on the same step as Gymnasium
        assert ref.STABILISE < n < ref.T and theirs["terminated"][-1]


@pytest.mark.parametrize("name", NAMES)
def test_truncation_at_time_limit(compiled, name):
    env, _, _, states = run(compiled, name, step_count0=envs.make(name).max_episode_steps - 3)
    expected = np.arange(1, ref.T + 1) >= 3
    np.testing.assert_array_equal(states.truncated, expected)
    assert states.step_count[2] == env.max_episode_steps


@pytest.mark.parametrize("name", NAMES)
def test_non_finite_action_rule(compiled, name):
    """A NaN/inf action acts as 0 and terminates that step; later steps are unaffected."""
    env, (gain, on, noise), _, _ = run(compiled, name)
    bad_steps = [5, 40]
    bad = noise.copy()
    bad[bad_steps[0]] = np.nan
    bad[bad_steps[1]] = -np.inf
    zero_on, zero = on.copy(), noise.copy()
    zero_on[bad_steps] = 0.0
    zero[bad_steps] = 0.0
    _, rollout = compiled[name]
    key = jax.random.key(0)
    _, with_bad = rollout(key, jnp.int32(0), gain, on, bad)
    _, with_zero = rollout(key, jnp.int32(0), gain, zero_on, zero)
    assert np.isfinite(np.asarray(with_bad.obs)).all()
    np.testing.assert_array_equal(np.asarray(with_bad.obs), np.asarray(with_zero.obs))
    flipped = np.asarray(with_bad.terminated) & ~np.asarray(with_zero.terminated)
    assert np.asarray(with_bad.terminated)[bad_steps].all()
    assert set(np.flatnonzero(flipped)) <= set(bad_steps)


@pytest.mark.parametrize("name", NAMES)
def test_reset_draws(compiled, name):
    """Initial states are within the documented ranges and differ between keys."""
    env, _, s0a, _ = run(compiled, name, key=1)
    _, _, s0b, _ = run(compiled, name, key=2)
    assert not np.array_equal(np.asarray(s0a.obs), np.asarray(s0b.obs))
    for s0 in (s0a, s0b):
        assert s0.obs.shape == (env.observation_size,) and s0.obs.dtype == jnp.float32
        assert s0.reward.dtype == jnp.float32 and s0.step_count.dtype == jnp.int32
        assert not s0.terminated and not s0.truncated and s0.step_count == 0
        if name == "Pendulum-v1":
            assert abs(s0.data.theta) <= np.pi and abs(s0.data.theta_dot) <= 1
        elif name == "InvertedDoublePendulum-v5":
            assert np.abs(np.asarray(s0.data.qpos)).max() <= 0.1
        else:
            assert np.abs(np.asarray(s0.data.qpos)).max() <= 0.01
            assert np.abs(np.asarray(s0.data.qvel)).max() <= 0.01


def test_pendulum_reset_distribution():
    env = envs.make("Pendulum-v1")
    states = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.key(0), 4096))
    theta, theta_dot = np.asarray(states.data.theta), np.asarray(states.data.theta_dot)
    assert np.abs(theta).max() <= np.pi and np.abs(theta_dot).max() <= 1
    assert abs(theta.mean()) < 0.1 and abs(theta_dot.mean()) < 0.05  # 3.5σ of the mean
    assert np.unique(theta).size == theta.size


def test_pendulum_vmapped_step_matches_gymnasium():
    """jit(vmap(step)) on 4096 instances; a few lanes checked against Gymnasium's step. One
    float32 step: a few roundings of values up to 8 (ulp 9.5e-7) and of rewards up to 16.3,
    so 1e-5 absolute and relative."""
    import gymnasium as gym

    env = envs.make("Pendulum-v1")
    n = 4096
    states = jax.vmap(env.reset)(jax.random.split(jax.random.key(1), n))
    actions = np.random.default_rng(0).uniform(-3, 3, (n, 1)).astype(np.float32)
    stepped = jax.jit(jax.vmap(env.step))(states, jnp.asarray(actions))
    assert stepped.obs.shape == (n, 3) and stepped.reward.shape == (n,)
    gym_env = gym.make("Pendulum-v1").unwrapped
    gym_env.reset(seed=0)
    for i in (0, 1234, n - 1):
        gym_env.state = np.array([states.data.theta[i], states.data.theta_dot[i]], np.float64)
        obs, reward, *_ = gym_env.step(actions[i])
        np.testing.assert_allclose(np.asarray(stepped.obs[i]), obs, atol=1e-5)
        np.testing.assert_allclose(float(stepped.reward[i]), reward, rtol=1e-5, atol=1e-5)


def test_interface():
    for name in NAMES:
        env = envs.make(name)
        assert env.name == name
        assert {env: 1}[env] == 1  # hashable, as a static argument of jax.jit must be
        for bound in (env.action_low, env.action_high):
            assert bound.dtype == np.float32 and bound.shape == (env.action_size,)
        assert env.dt > 0 and env.max_episode_steps > 0
    assert envs.make().name == "InvertedPendulum-v5"
    expected = {
        "InvertedPendulum-v5": (4, 3.0, 0.04, 1000),
        "InvertedPendulum-v4": (4, 3.0, 0.04, 1000),
        "InvertedPendulumBullet-v0": (5, 1.0, 0.04, 1000),
        "InvertedDoublePendulum-v5": (9, 1.0, 0.05, 1000),
        "Pendulum-v1": (3, 2.0, 0.05, 200),
    }
    for name, (obs_size, high, dt, steps) in expected.items():
        env = envs.make(name)
        assert (env.observation_size, env.action_high[0], env.max_episode_steps) == (
            obs_size, high, steps)
        assert env.dt == pytest.approx(dt)


def test_lean_stages_default_follows_the_backend(monkeypatch):
    """MJX envs take the lean RK4 stages (`MjxEnv._rk4_lean`) except on a CPU, unless told;
    tests/test_envs_x64.py checks both forms against Gymnasium."""
    env = envs.make("InvertedPendulum-v5")
    assert env.lean_stages is None and not env._uses_lean_stages()  # the CPU here
    monkeypatch.setattr(jax, "default_backend", lambda: "gpu")
    assert env._uses_lean_stages()
    env.lean_stages = False
    assert not env._uses_lean_stages()


@pytest.mark.parametrize("lean", [False, True])
def test_a_vmapped_step_traces_the_forward_once_and_batches_each_scan_once(monkeypatch, lean):
    """Tracing a vmapped step traces MuJoCo's forward once in either RK4 form (the lean form's
    two calls share one jitted trace) and batches each scan body in one pass: the RK4 sums
    start batched (`envs.mjx_env._zero_sums`), so JAX's scan batching rule needs no second
    pass. Passes are counted at JAX 0.10's `batching.batch_jaxpr`, called once per pass."""
    from jax._src.lax.control_flow import loops

    from envs import active_set_solver

    env = envs.make("InvertedPendulum-v5")
    env.lean_stages = lean
    states = jax.vmap(env.reset)(jax.random.split(jax.random.key(0), 4))
    passes, forwards = [], []
    batch_jaxpr, forward = loops.batching.batch_jaxpr, active_set_solver.forward
    monkeypatch.setattr(loops.batching, "batch_jaxpr", lambda jaxpr, *args, **kwargs:
                        passes.append(id(jaxpr)) or batch_jaxpr(jaxpr, *args, **kwargs))
    monkeypatch.setattr(active_set_solver, "forward",
                        lambda *args: forwards.append(1) or forward(*args))
    jax.make_jaxpr(jax.vmap(env.step))(states, jnp.zeros((4, env.action_size)))
    assert len(forwards) == 1
    assert passes and len(passes) == len(set(passes)), passes


def test_errors():
    with pytest.raises(ValueError, match="CartPole-v1.*InvertedPendulum-v5"):
        envs.make("CartPole-v1")
    with pytest.raises(TypeError, match="'frame_skp'"):
        envs.make("InvertedPendulum-v5", frame_skp=3)
    with pytest.raises(ValueError, match="-0.5"):
        envs.make("InvertedPendulum-v5", reset_noise_scale=-0.5)
    with pytest.raises(ValueError, match="max_episode_steps.*0"):
        envs.make("Pendulum-v1", max_episode_steps=0)
    with pytest.raises(TypeError, match="'100'"):
        envs.make("Pendulum-v1", max_episode_steps="100")
    with pytest.raises(ValueError, match="nan"):
        envs.make("InvertedDoublePendulum-v5", healthy_reward=float("nan"))
    with pytest.raises(ValueError, match="num_envs"):
        envs.VectorEnv(envs.make("Pendulum-v1"), 0)
    env = envs.make("Pendulum-v1")
    with pytest.raises(ValueError, match=r"action shape \(2,\)"):
        env.step(env.reset(jax.random.key(0)), jnp.zeros(2))


def python_in_a_new_process(code: str) -> str:
    """Runs `code` in a new Python process (imports as a user's would be), asserting it
    succeeds; returns its stdout."""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-3000:]
    return out.stdout


def test_import_and_mjx_build_print_nothing_and_load_no_warp():
    """`import envs` leaves MJX unimported (a Pendulum-v1 run never needs it); building an MJX
    environment imports it without MJX's "Failed to import warp" line, and without Warp
    where warp-lang is installed (`envs._lean_import`), leaving `import warp` to work afterwards."""
    code = ("import sys, envs; assert 'mujoco.mjx' not in sys.modules; "
            "envs.make('InvertedPendulum-v5'); assert 'mujoco.mjx' in sys.modules; "
            "assert 'warp' not in sys.modules, sys.modules['warp']")
    assert python_in_a_new_process(code) == ""


MESH_ON_A_FLOOR = """<mujoco><asset><mesh name="m" vertex="0 0 0 1 0 0 0 1 0 0 0 1"/></asset>
<worldbody><geom type="plane" size="1 1 1"/>
<body pos="0 0 1"><freejoint/><geom type="mesh" mesh="m"/></body></worldbody></mujoco>"""


def test_trimesh_and_scipy_spatial_are_imported_only_when_mjx_needs_them():
    """Building an MJX environment leaves trimesh and scipy.spatial unimported
    (`envs._lean_import.deferred`); a model whose mesh collides, put on the device, imports
    them: MJX's convex hull (the tetrahedron's 4 vertices) is computed with the real
    `trimesh.Trimesh`, and MJX's `spatial` is the real module."""
    code = ("import sys, envs, mujoco; envs.make('InvertedPendulum-v5'); "
            "assert not {'trimesh', 'scipy.spatial'} & set(sys.modules); "
            "from envs._mjx import mjx; from mujoco.mjx._src import mesh; "
            f"m = mjx.put_model(mujoco.MjModel.from_xml_string({MESH_ON_A_FLOOR!r})); "
            "import trimesh, scipy.spatial; assert mesh.trimesh.Trimesh is trimesh.Trimesh; "
            "assert mesh.spatial.ConvexHull is scipy.spatial.ConvexHull; "
            "assert m._impl.mesh_convex[0].vert.shape == (4, 3), m._impl.mesh_convex")
    python_in_a_new_process(code)


def test_a_deferred_module_is_the_real_one_at_first_use():
    """`deferred`'s stand-in answers its placeholders without importing the module while open,
    imports it at any other lookup, and leaves `import` to the real module afterwards."""
    from envs import _lean_import

    name = "json"  # imported already: nothing is deferred
    with _lean_import.deferred(name, "dumps"):
        assert sys.modules[name].dumps.__module__ == "json"
    code = ("import sys; from envs import _lean_import; assert 'wave' not in sys.modules\n"
            "with _lean_import.deferred('wave', 'Wave_read'):\n"
            "    import wave\n"
            "    placeholder = wave.Wave_read\n"
            "    assert placeholder.__module__ == 'wave' and 'wave' in sys.modules\n"
            "    assert type(sys.modules['wave']).__name__ == '_Deferred'\n"
            "assert 'wave' not in sys.modules\n"
            "assert wave.Wave_read is not placeholder and wave.open is sys.modules['wave'].open\n"
            "import wave as real\n"
            "assert wave.Wave_read is real.Wave_read and type(real).__name__ == 'module'")
    python_in_a_new_process(code)


def test_another_mujoco_version_is_refused_in_one_line():
    from envs import _mjx
    _mjx.check_versions()  # the installed, pinned versions pass
    with pytest.raises(ImportError, match=r"^envs needs mujoco-mjx==3\.17\.0 .*found 3\.18\.0: "
                                          r"pip install mujoco-mjx==3\.17\.0$"):
        _mjx.check_versions({"mujoco": "4.0.0", "mujoco-mjx": "3.18.0"})


def test_every_registered_environment_has_a_spec_that_builds_it():
    for name in NAMES:
        spec = envs.spec(name)
        env = spec.factory(name)
        assert spec.name == env.name == name and spec.renderer in ("mujoco", "pendulum")
        assert spec.solved_return is not None
    with pytest.raises(ValueError, match="unknown environment 'CartPole-v9'; registered: "):
        envs.spec("CartPole-v9")
