"""MuJoCo Playground tasks by name (envs/playground.py): the adapter against the Playground
task stepped directly (same draws, same observations and rewards, the time limit a truncation
that keeps the true final observation, `done` a termination, actions clipped to the task's
bounds), the one-line errors, and a short CPU run on CartpoleBalance whose delivered policy is
scored in the Playground task itself."""

import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import envs
import sac_jax
from envs import playground
from sac_jax.run import run_training
from sac_jax.saved_policy import SavedPolicy
from sac_jax.train import agent_for
from tests.subprocess_json import ROOT
from tests.task_steps import side_by_side

registry = pytest.importorskip("mujoco_playground").registry
NAME = "playground/CartpoleBalance"


@pytest.fixture(scope="module")
def env():
    return envs.make(NAME)


def test_the_task_list_is_playgrounds_control_suite():
    from mujoco_playground import dm_control_suite

    assert playground.TASKS == tuple(dm_control_suite.ALL_ENVS)
    assert all(envs.spec(playground.PREFIX + t).gymnasium_id is None for t in playground.TASKS)
    assert set(envs.registered()) >= {playground.PREFIX + t for t in playground.TASKS}
    solved = {t: envs.spec(playground.PREFIX + t).solved_return for t in playground.TASKS}
    assert {t: r for t, r in solved.items() if r is not None} == {  # SAC's after 1M steps, floored
        "CartpoleBalance": 900.0, "CartpoleSwingup": 800.0, "PendulumSwingup": 300.0}


def test_steps_are_the_tasks_own_until_the_limit_truncates_with_the_final_observation(env):
    """1000 steps of a fixed action sequence through the adapter and through the raw task from
    the same key: observations and rewards equal at every step; the adapter truncates at step
    1000 exactly (the task itself never ends), and its last observation is the task's."""
    task = registry.load("CartpoleBalance", config_overrides={"impl": "jax"})
    actions = jax.random.uniform(jax.random.key(1), (env.max_episode_steps, 1), minval=-1,
                                 maxval=1)

    key = jax.random.key(7)
    (obs, reward, terminated, truncated), (task_obs, task_reward, done) = side_by_side(
        env, task, key, actions)
    np.testing.assert_array_equal(env.reset(key).obs, task.reset(key).obs)
    np.testing.assert_array_equal(obs, task_obs)
    np.testing.assert_array_equal(reward, task_reward)
    assert not np.any(done) and not np.any(terminated)
    assert np.flatnonzero(truncated).tolist() == [env.max_episode_steps - 1]
    assert env.max_episode_steps == 1000


def test_done_is_a_termination_and_a_non_finite_action_too(env):
    state = env.reset(jax.random.key(0))
    broken = state.replace(data=state.data.replace(
        data=state.data.data.replace(qpos=state.data.data.qpos * jnp.nan)))
    assert bool(env.step(broken, jnp.zeros(1)).terminated)  # the task's done: a NaN state
    after = env.step(state, jnp.array([jnp.nan]))
    assert bool(after.terminated) and np.all(np.isfinite(after.obs))
    assert not bool(env.step(state, jnp.zeros(1)).terminated)


def test_actions_are_clipped_to_the_tasks_bounds_and_resets_draw_fresh_starts(env):
    np.testing.assert_array_equal(env.action_low, [-1.0])
    np.testing.assert_array_equal(env.action_high, [1.0])
    state = env.reset(jax.random.key(0))
    np.testing.assert_array_equal(env.step(state, jnp.array([5.0])).obs,
                                  env.step(state, jnp.array([1.0])).obs)
    # MJX clamps ctrl itself, so equal observations alone would not show that the task gets
    # the clipped action (its reward reads the action it is given)
    np.testing.assert_array_equal(env.step(state, jnp.array([5.0])).data.data.ctrl, [1.0])
    np.testing.assert_array_equal(env.step(state, jnp.array([-5.0])).data.data.ctrl, [-1.0])
    starts = jax.vmap(env.reset)(jax.random.split(jax.random.key(0), 8)).obs
    assert len({tuple(np.asarray(o)) for o in starts}) == 8


def test_unknown_names_and_a_missing_playground_fail_in_one_line(monkeypatch):
    with pytest.raises(ValueError, match=r"^unknown Playground task 'playground/CartpoleBalanc'; "
                                         r"did you mean playground/CartpoleBalance"):
        envs.make("playground/CartpoleBalanc")
    with pytest.raises(ValueError, match=r"^unknown environment 'InvertedPendulum-v6'; did you "
                                         r"mean InvertedPendulum-v5"):
        envs.make("InvertedPendulum-v6")
    monkeypatch.setitem(sys.modules, "mujoco_playground", None)  # as if not installed
    playground._load.cache_clear()
    try:
        with pytest.raises(ValueError) as raised:
            envs.make("playground/CartpoleSwingup")
    finally:
        playground._load.cache_clear()
    assert str(raised.value) == ("environment 'playground/CartpoleSwingup' needs MuJoCo "
                                 "Playground: pip install -e \".[playground]\"")


def test_building_an_mjx_task_prints_nothing_and_loads_no_warp_or_torch():
    """MJX and Playground import Warp where it is installed, and print "Failed to import
    (mujoco_)warp" where not; Playground imports PyTorch where installed. An MJX task (the
    default impl) is built with both hidden (`envs._lean_import`), so none of that happens:
    the output is the task's alone."""
    code = ("import sys, envs; "
            "print(envs.make('playground/CartpoleBalance').observation_size, "
            "'warp' in sys.modules, 'torch' in sys.modules)")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=300, check=True)
    assert proc.stdout == "5 False False\n"


def test_mujoco_warnings_while_a_task_is_built_are_python_warnings_and_leave_no_log(tmp_path):
    """CheetahRun's model uses a deprecated MuJoCo attribute: MuJoCo's own handler would print
    the warning to stdout and append it to MUJOCO_LOG.TXT in the working directory. It comes
    as a Python warning instead, and MuJoCo's handler is restored afterwards."""
    code = ("import mujoco, envs; envs.make('playground/CheetahRun'); "
            "print(mujoco.get_mju_user_warning())")
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                          text=True, timeout=300, check=True,
                          env=dict(os.environ, PYTHONPATH=ROOT))
    assert proc.stdout == "None\n"
    assert "UserWarning: MuJoCo: compiler attribute 'settotalmass' is deprecated" in proc.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("before, message", [
    ("import sys; sys.modules['warp'] = None",
     " needs MuJoCo Warp: pip install -e \".[playground]\""),
    ("envs.make('InvertedPendulum-v5')",
     ": this process has loaded MJX without Warp (for an MJX task built before); build Warp tasks "
     "in a process of their own")])
def test_a_warp_task_without_warp_is_refused_in_one_line(before, message):
    """Without Warp installed, or once an MJX environment has loaded MJX without it (MJX loads
    its Warp backend only if Warp is imported first, which a Warp task does), a Warp task is
    refused in one line."""
    if "InvertedPendulum" in before:
        pytest.importorskip("warp")
    code = f"import envs; {before}; envs.make('playground/CartpoleBalance', impl='warp')"
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 1
    assert proc.stderr.strip().splitlines()[-1] == (
        f"ValueError: playground/CartpoleBalance with impl='warp'{message}")


def test_a_warp_task_steps_without_a_line_per_kernel_module(tmp_path):
    """With MuJoCo Warp (`impl="warp"`), Warp logs a line per kernel module it loads, dozens
    per step program; a task built by name keeps its log at warnings (here on the CPU, from
    an empty kernel cache)."""
    pytest.importorskip("warp")
    code = (f"import warp; warp.config.kernel_cache_dir = {str(tmp_path)!r}; "
            "import jax, jax.numpy as jnp, envs; "
            "env = envs.make('playground/CartpoleBalance', impl='warp'); "
            "state = jax.jit(env.step)(env.reset(jax.random.key(0)), "
            "jnp.zeros(env.action_size)); print(float(state.reward) > 0)")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=600, check=True)
    assert proc.stdout == "True\n"
    assert "load on device" not in proc.stdout + proc.stderr, proc.stderr[-2000:]


def test_the_configs_env_impl_chooses_the_tasks_backend(monkeypatch):
    """`SACConfig.env_impl` reaches `registry.load`'s `impl` (MJX by default); on our own
    environments, which have no choice, it is refused naming the field."""
    loaded = []
    monkeypatch.setattr(playground, "_load",
                        lambda task, impl: loaded.append((task, impl)) or env_task())
    config = sac_jax.PRESETS["CartpoleBalance"]
    config.make_env()
    config.replace(env_impl="warp").make_env()
    assert loaded == [("CartpoleBalance", "jax"), ("CartpoleBalance", "warp")]
    with pytest.raises(ValueError, match=r"^SACConfig.env_impl='warp': only MuJoCo Playground"):
        sac_jax.SACConfig(env_impl="warp")


def test_a_tasks_observation_size_is_read_once_however_often_its_env_is_built(monkeypatch):
    """Reading Playground's `observation_size` traces the task's reset (0.3-1.1 s), and a run
    builds its environment several times: the adapter reads it once per task."""
    task = env_task()
    reads = []
    monkeypatch.setattr(type(task), "observation_size", property(
        lambda self: reads.append(1) or {"state": (5,)}))
    monkeypatch.setattr(playground, "_load", lambda name, impl: task)
    sizes = [envs.make(NAME).observation_size for _ in range(3)]
    assert sizes == [5, 5, 5] and reads == [1]


def env_task():
    return registry.load("CartpoleBalance", config_overrides={"impl": "jax"})


def test_the_train_script_names_close_tasks_in_one_line(tmp_path):
    proc = subprocess.run([sys.executable, "scripts/train.py", "--env", "playground/Cartpole",
                           "--out", str(tmp_path / "run")], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert "did you mean playground/Cartpole" in proc.stderr
    assert not (tmp_path / "run").exists()


def test_without_playground_the_train_script_says_what_to_install(tmp_path):
    """scripts/train.py where `import mujoco_playground` fails: one line, exit 2, nothing
    written."""
    code = ("import sys; sys.modules['mujoco_playground'] = None; from scripts import train; "
            "sys.exit(train.main(sys.argv[1:]))")
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-c", code, "--env", "playground/CartpoleSwingup",
                           "--out", str(out)], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 2
    assert proc.stderr.strip() == ("error: environment 'playground/CartpoleSwingup' needs MuJoCo "
                                   "Playground: pip install -e \".[playground]\"")
    assert not out.exists()


@pytest.mark.slow
def test_the_cartpole_balance_preset_delivers_a_policy_that_balances_in_the_playground_task():
    """The CartpoleBalance preset, 1 seed: the delivered actor, run deterministically in the raw
    Playground task (no adapter, 5 fresh starts, 1000 steps), scores at least the solved 900 of
    1000."""
    config = sac_jax.PRESETS["CartpoleBalance"]
    assert config.env == NAME
    result = run_training(config, seeds=1)
    agent, _ = agent_for(config)
    policy = SavedPolicy(config, {}, 0, agent, jax.tree_util.tree_map(
        lambda x: x[0], result.state.delivered.actor_params))
    task = registry.load("CartpoleBalance", config_overrides={"impl": "jax"})

    def episode(key):
        def step(state, _):
            state = task.step(state, agent.act(policy.actor_params, state.obs[None])[0])
            return state, state.reward
        return jax.lax.scan(step, task.reset(key), length=1000)[1].sum()

    returns = jax.jit(jax.vmap(episode))(jax.random.split(jax.random.key(2026), 5))
    assert float(returns.mean()) >= 900, returns
