"""An adapted task (envs/task_adapter.py) and the task it wraps, stepped side by side."""

import jax


def side_by_side(env, task, key, actions):
    """`actions` (T, action_size) through `env` and through the raw `task`, both from
    `reset(key)`, each in one jitted scan: ((obs, reward, terminated, truncated) of ours,
    (obs, reward, done) of the task's), each with a leading axis T."""
    def ours(state, action):
        state = env.step(state, action)
        return state, (state.obs, state.reward, state.terminated, state.truncated)

    def theirs(state, action):
        state = task.step(state, action)
        return state, (state.obs, state.reward, state.done)

    return (jax.jit(lambda: jax.lax.scan(ours, env.reset(key), actions))()[1],
            jax.jit(lambda: jax.lax.scan(theirs, task.reset(key), actions))()[1])
