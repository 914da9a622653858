"""Whole training loops: sac_jax's `make_train` loop against seed 002's loop
(references/loop.py), both fed the same recorded stream of random draws
(`sac_jax.record_draws`) from the same initial weights and environment state.

`measure(name, dtype, mutations)` runs both for the whole run of `CONFIGS[name]` (sac_jax
chunk by chunk from the host, as `sac_jax.run` drives it) and returns, at the end:

    params, params_abs   per tensor max|theta_jax - theta_ref| / max|theta_ref| (max over
                         tensors) and max abs, over actor, critics and critic targets
    alpha, log_alpha     |alpha_jax - alpha_ref| / alpha_ref, |log alpha_jax - log alpha_ref|
    buffer               max abs difference over every stored field of the two replay buffers
    updates, buffer_size updates done and transitions held, by sac_jax and the reference
    params_by_chunk      `params` after each chunk of the run (at env_steps_by_chunk)
    <mutation>/<error>   the same against a reference with a planted bug (`MUTATIONS`)

Run as `JAX_ENABLE_X64=1 python -m tests.equivalence_loop [name ...]` for float64 (with the
mutations for "seed"): prints one JSON object {name: errors} on the last line
(test_equivalence_loop.py does so in a subprocess).
"""

from __future__ import annotations

import dataclasses
import json
import os
import sys
from typing import Dict

import jax
import numpy as np
import torch

import envs
import sac_jax
from sac_jax import selection
from sac_jax.train import make_train_parts
from tests.equivalence_harness import (max_abs, max_rel, params_of, reference_alpha,
                                       reference_log_alpha, rel, state_from_reference)
from references import loop, transfer
from references.cleanrl_sac import CleanRLSAC

HIDDEN = 64
# Seed 002's SAC on Pendulum-v1 (pure JAX, compiles quickly; episodes truncated at 200 steps),
# small networks, 512 environment steps after learning starts; a replay capacity below the run's
# steps, so the ring buffer wraps around while learning; an evaluation point every 128 steps,
# so the host drives 5 chunks (the prefill, then one per point), each compared at its end.
# "seed" has the seed's loop shape (one environment, one update per step); "vector" two
# environments and two updates per step.
_BASE = sac_jax.PRESETS["cleanrl"].replace(
    env="Pendulum-v1", learning_starts=128, total_steps=640, eval_every=128, eval_episodes=1,
    buffer_size=384, batch_size=64, actor_hidden=(HIDDEN, HIDDEN),
    critic_hidden=(HIDDEN, HIDDEN))
CONFIGS = {
    "seed": _BASE,
    "vector": _BASE.replace(num_envs=2, updates_per_step=2),
}


def _buffer_of_reference(rb: loop.ReplayBuffer) -> Dict[str, np.ndarray]:
    """The reference buffer in sac_jax's flat slot order (slot = row * n_envs + env)."""
    flat = lambda x: x.reshape((-1,) + x.shape[2:])
    return {"obs": flat(rb.observations), "action": flat(rb.actions), "reward": flat(rb.rewards),
            "next_obs": flat(rb.next_observations), "terminated": flat(rb.dones)}


class _StaleObsOnce(loop.ReplayBuffer):
    """Mutation "stale_obs": the 200th transition is stored with the previous step's
    observation, as if `obs = next_obs` had been skipped once."""

    def __init__(self, *args):
        super().__init__(*args)
        self._calls, self._previous = 0, None

    def add(self, obs, *rest):
        self._calls += 1
        stored = self._previous if self._calls == 200 else obs
        self._previous = obs
        super().add(stored, *rest)


MUTATIONS = ("policy_delay_phase", "stale_obs")
"""Bugs planted in the reference to show the comparison detects them: "policy_delay_phase"
passes global_step + 1 to the update (the actor block on the other half of the updates);
"stale_obs" see `_StaleObsOnce`."""


def _run_reference(config, env, initial_env, draws, torch_dtype, key_seed, ours, mutation=None
                   ) -> Dict[str, object]:
    """Seed 002's loop from the same initial weights (seed `key_seed`) and environment state;
    the errors against `ours` (sac_jax's runner after each chunk) at the end, and the
    parameter errors at every chunk's end."""
    ref = CleanRLSAC(env.observation_size, env.action_size, env.action_low, env.action_high,
                     seed=key_seed, dtype=torch_dtype, hidden=HIDDEN)
    if mutation == "policy_delay_phase":
        update = ref.update
        ref.update = lambda data, noise, global_step: update(data, noise, global_step + 1)
    buffer_class = _StaleObsOnce if mutation == "stale_obs" else loop.ReplayBuffer
    rb = buffer_class(config.buffer_size, env.observation_size, env.action_size, config.num_envs)
    steps = loop.train(ref, loop.JaxVectorEnv(envs.VectorEnv(env, config.num_envs), initial_env),
                       rb, draws, config.prefill_iterations, torch_dtype)
    ours_at = {int(runner.iteration): runner for runner in ours}
    by_chunk = []
    for iterations, updates in enumerate(steps, start=1):
        if iterations in ours_at:
            by_chunk.append(_errors(ours_at[iterations], ref, rb, updates))
    return dict(by_chunk[-1], params_by_chunk=[e["params"] for e in by_chunk])


def _errors(runner, ref, rb, updates) -> Dict[str, float]:
    ref_params, ours = transfer.to_flax(ref.networks()), params_of(runner.sac)
    return {
        "params": max_rel(ours, ref_params),
        "params_abs": max_abs(ours, ref_params),
        "alpha": rel(runner.sac.alpha, reference_alpha(ref)),
        "log_alpha": abs(float(runner.sac.log_alpha) - reference_log_alpha(ref)),
        "buffer": max(float(np.max(np.abs(np.asarray(getattr(runner.buffer.data, k), np.float64)
                                          - v))) for k, v in _buffer_of_reference(rb).items()),
        "updates": int(runner.sac.step),
        "updates_reference": updates,
        "buffer_size": int(runner.buffer.size),
        "buffer_size_reference": rb.size(),
    }


def measure(name: str, dtype: str = "float32", mutations=(), key_seed: int = 0
            ) -> Dict[str, float]:
    """The errors of the module docstring, plus "<mutation>/<error>" for each mutation."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # PyTorch's intra-op threads only contend on a small machine
    try:
        return _measure(name, dtype, mutations, key_seed)
    finally:
        torch.set_num_threads(threads)


def _measure(name: str, dtype: str, mutations, key_seed: int) -> Dict[str, float]:
    if dtype == "float64" and not jax.config.jax_enable_x64:
        raise RuntimeError("float64 needs JAX_ENABLE_X64=1")
    torch_dtype = {"float32": torch.float32, "float64": torch.float64}[dtype]
    config = CONFIGS[name]
    env = envs.make(config.env)
    parts = make_train_parts(config)
    agent = sac_jax.make_agent(config, env.observation_size, env.action_size, env.action_low,
                               env.action_high)

    key = jax.random.key(key_seed)
    draws = jax.jit(parts.record_draws)(key)
    parts = make_train_parts(config, randomness=sac_jax.replay(config, draws))
    runner = jax.jit(parts.init)(key)
    initial_env = runner.env
    # the reference's initial weights (each reference run starts from the same ones: seed)
    initial = CleanRLSAC(env.observation_size, env.action_size, env.action_low, env.action_high,
                         seed=key_seed, dtype=torch_dtype, hidden=HIDDEN)
    sac = state_from_reference(agent, initial, np.dtype(dtype))
    runner = runner.replace(sac=sac, delivered=selection.init(sac.actor_params))

    chunk = jax.jit(parts.chunk)  # driven from the host chunk by chunk, as sac_jax.run does
    ours = []
    for _ in range(parts.num_chunks):
        runner = chunk(runner)
        ours.append(jax.device_get(runner))
    stream = _numpy(draws)
    errors = {"env_steps": int(runner.iteration) * config.num_envs,
              "env_steps_by_chunk": [int(r.iteration) * config.num_envs for r in ours]}
    for mutation in (None,) + tuple(mutations):
        found = _run_reference(config, env, initial_env, stream, torch_dtype, key_seed, ours,
                               mutation)
        errors.update({k if mutation is None else f"{mutation}/{k}": v for k, v in found.items()})
    return errors


def _numpy(draws: sac_jax.Draws) -> Dict:
    """`Draws` as the reference loop reads it: a dict of numpy arrays."""
    return {f.name: jax.tree_util.tree_map(np.array, getattr(draws, f.name))
            for f in dataclasses.fields(draws)}


def main(names):
    if os.environ.get("JAX_ENABLE_X64", "").lower() not in ("1", "true"):
        raise SystemExit("set JAX_ENABLE_X64=1")
    from sac_jax.compilation_cache import enable_compilation_cache

    assert jax.config.jax_enable_x64
    enable_compilation_cache()
    print(json.dumps({n: measure(n, "float64", MUTATIONS if n == "seed" else ())
                      for n in (names or list(CONFIGS))}))


if __name__ == "__main__":
    main(sys.argv[1:])
