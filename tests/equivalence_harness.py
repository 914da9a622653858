"""Shared machinery of the equivalence tests: sac_jax (preset) against a PyTorch reference
(references/) with the same weights, batches and noise.

`measure(family, dtype)` runs every comparison for one seed family and returns the max errors:

    action, log_prob        max |a_jax - a_ref|, max |log pi_jax - log pi_ref| on one batch
    log_prob_conditioned    max over samples of |log pi_jax - log pi_ref| / `log_prob_tolerance`
    <name>_loss             |L_jax - L_ref| / |L_ref| for each loss of one full update
    <name>_grad             per tensor max|g_jax - g_ref| / max|g_ref|, max over tensors
    log_pi                  max |.| of the log pi the actor steps saw
    step_params, step_alpha max |theta_jax - theta_ref| over every parameter (targets included)
                            and |alpha_jax - alpha_ref| after that update
    run_params, run_alpha   after 25, 50, .., 200 updates on identical batches and noise:
                            per tensor max|theta_jax - theta_ref| / max|theta_ref| (max over
                            tensors and checkpoints), and |alpha_jax - alpha_ref| / alpha_ref
    run_params_torch32_vs_torch64, run_params_jax32_vs_torch64 (float32 only)
                            controls: the same run of the reference in float64 against the
                            float32 reference and against sac_jax in float32

JAX gradients are `jax.grad` of loss functions built here from `sac_jax.losses`, evaluated at
the states that `sac_jax.update_*` produce in the preset's update order; the updated
parameters come from `sac_jax.sac_update`. dtype float64 needs JAX_ENABLE_X64=1 (see
tests/equivalence_x64.py).
"""

from __future__ import annotations

import functools
from typing import Dict

import jax
import jax.numpy as jnp
import numpy as np
import torch

import sac_jax
from sac_jax import losses
from sac_jax.updates import (actor_objective, critic_objective, update_actor, update_critic,
                             update_temperature, update_value, value_objective)
from references import cleanrl_sac, pendulum_sac, sac_v1, transfer
from tests.pendulum_shapes import cast_floats

BATCH = 64
RUN_UPDATES = 200
CHECKPOINTS = (25, 50, 75, 100, 125, 150, 175, 200)

# family -> (preset, observation size, action size, action low, action high, reference module)
FAMILIES = {
    "cleanrl": ("cleanrl", 4, 1, -3.0, 3.0, cleanrl_sac),   # seed 002, InvertedPendulum-v4
    "pendulum": ("pendulum", 3, 1, -2.0, 2.0, pendulum_sac),  # seed 001, Pendulum-v1
    "v1": ("v1", 5, 1, -1.0, 1.0, sac_v1),                  # seeds 000/003, Bullet pendulum
}
PARAM_NAMES = ("actor", "critic", "critic_target", "value", "value_target")


# ---------------------------------------------------------------------------- construction
def make_reference(family: str, dtype=torch.float32):
    _, obs, act, low, high, module = FAMILIES[family]
    if family == "cleanrl":
        return cleanrl_sac.CleanRLSAC(obs, act, [low] * act, [high] * act, seed=0, dtype=dtype)
    if family == "pendulum":
        return pendulum_sac.SAC(obs, act, [low] * act, [high] * act, hidden_dim=64, seed=1,
                                dtype=dtype)
    return sac_v1.SoftActorCritic(obs, act, max_action=[high] * act, reward_scale=2, seed=0,
                                  dtype=dtype)


def make_agent(family: str):
    preset, obs, act, low, high, _ = FAMILIES[family]
    return sac_jax.make_agent(sac_jax.PRESETS[preset], obs, act, low, high)


def reference_alpha(ref) -> float:
    """The reference's current temperature (a Python float in seed 002, a tensor in seed 001
    after its first step, fixed at 1 in SAC v1)."""
    if not hasattr(ref, "alpha"):
        return 1.0
    if isinstance(ref.alpha, torch.Tensor):
        return float(ref.alpha.detach().reshape(-1)[0])
    return float(ref.alpha)


def reference_log_alpha(ref) -> float:
    return float(ref.log_alpha.detach().reshape(-1)[0]) if hasattr(ref, "log_alpha") else 0.0


def state_from_reference(agent, ref, dtype) -> sac_jax.SACState:
    """A fresh `agent.init` state with the reference's weights and temperature, all floats in
    `dtype`, optimiser states zero (as the reference's fresh Adam)."""
    state = cast_floats(agent.init(jax.random.PRNGKey(0)), dtype)
    params = transfer.to_flax(ref.networks())
    as_jax = lambda tree: jax.tree_util.tree_map(lambda x: jnp.asarray(x, dtype), tree)
    state = state.replace(**{f"{name}_params": as_jax(p) for name, p in params.items()})
    if agent.config.variant == "v1":
        assert reference_alpha(ref) == float(state.alpha) == 1.0
    else:
        assert abs(reference_alpha(ref) - float(state.alpha)) == 0.0
        assert reference_log_alpha(ref) == float(state.log_alpha)
    return state


# ---------------------------------------------------------------------------- data
def random_batch(rng: np.random.Generator, family: str, np_dtype) -> Dict[str, np.ndarray]:
    _, obs, act, low, high, _ = FAMILIES[family]
    return {"obs": rng.standard_normal((BATCH, obs)).astype(np_dtype),
            "action": rng.uniform(low, high, (BATCH, act)).astype(np_dtype),
            "reward": rng.uniform(0.0, 1.0, BATCH).astype(np_dtype),
            "next_obs": rng.standard_normal((BATCH, obs)).astype(np_dtype),
            "terminated": (rng.random(BATCH) < 0.1).astype(np_dtype)}


def random_noise(rng: np.random.Generator, agent, np_dtype) -> Dict[str, np.ndarray]:
    k, a = agent.config.policy_frequency, agent.action_size
    return {"critic": rng.standard_normal((BATCH, a)).astype(np_dtype),
            "value": rng.standard_normal((BATCH, a)).astype(np_dtype),
            "actor": rng.standard_normal((k, BATCH, a)).astype(np_dtype),
            "temperature": rng.standard_normal((k, BATCH, a)).astype(np_dtype)}


def jax_batch(b) -> sac_jax.Transition:
    return sac_jax.Transition(obs=jnp.asarray(b["obs"]), action=jnp.asarray(b["action"]),
                              reward=jnp.asarray(b["reward"]), next_obs=jnp.asarray(b["next_obs"]),
                              terminated=jnp.asarray(b["terminated"]))


def reference_update(family: str, ref, b, noise, count: int, dtype):
    """One update of the reference in its seed's form; `count` is the JAX state's step + 1
    (CleanRL: global_step = learning_starts + count, the seed's first update being at
    learning_starts + 1)."""
    module = FAMILIES[family][5]
    batch = module.make_batch(b["obs"], b["action"], b["reward"], b["next_obs"], b["terminated"],
                              dtype=dtype)
    t = lambda x: torch.as_tensor(x, dtype=dtype)
    if family == "cleanrl":
        global_step = sac_jax.PRESETS["cleanrl"].learning_starts + count
        return ref.update(batch, {"critic": t(noise["critic"]),
                                  "actor": [t(x) for x in noise["actor"]],
                                  "temperature": [t(x) for x in noise["temperature"]]},
                          global_step)
    if family == "pendulum":
        return ref.update(batch, {"critic": t(noise["critic"]), "actor": t(noise["actor"][0])})
    return ref.learn(batch, {"value": t(noise["value"]), "actor": t(noise["actor"][0])})


@functools.partial(jax.jit, static_argnums=0)
def jax_probe(agent, state, batch, noise):
    """Losses and gradients of one full update in `update_order` (the actor block assumed to
    run), each at the state the preceding `sac_jax.update_*` calls produce."""
    cfg, out = agent.config, {"actor_loss": [], "actor_grad": [], "log_pi": [],
                              "alpha_loss": [], "alpha_grad": []}
    for name in cfg.update_order:
        if name == "critic":
            (out["critic_loss"], _), out["critic_grad"] = jax.value_and_grad(
                critic_objective(agent, state, batch, noise["critic"]),
                has_aux=True)(state.critic_params)
            state, _ = update_critic(agent, state, batch, noise["critic"])
        elif name == "value":
            out["value_loss"], out["value_grad"] = jax.value_and_grad(
                value_objective(agent, state, batch.obs, noise["value"]))(state.value_params)
            state, _ = update_value(agent, state, batch.obs, noise["value"])
        else:
            for k in range(cfg.policy_frequency):
                (loss, log_pi), grad = jax.value_and_grad(
                    actor_objective(agent, state, batch.obs, noise["actor"][k]),
                    has_aux=True)(state.actor_params)
                out["actor_loss"].append(loss)
                out["actor_grad"].append(grad)
                out["log_pi"].append(log_pi)
                state, metrics = update_actor(agent, state, batch.obs, noise["actor"][k])
                if cfg.learn_alpha:
                    log_prob = metrics["log_prob"]
                    if cfg.alpha_log_prob == "resample":
                        _, log_prob = agent.sample_action(state.actor_params, batch.obs,
                                                          noise["temperature"][k])
                    loss, grad = jax.value_and_grad(losses.temperature_loss)(
                        state.log_alpha, log_prob, agent.hyperparams.target_entropy, cfg.alpha_loss)
                    out["alpha_loss"].append(loss)
                    out["alpha_grad"].append(grad)
                    state, _ = update_temperature(agent, state, log_prob)
    return out


jit_sample_action = jax.jit(lambda agent, params, obs, eps: agent.sample_action(params, obs, eps),
                            static_argnums=0)
jit_sac_update = jax.jit(sac_jax.sac_update)


# ---------------------------------------------------------------------------- errors
def _leaves(tree):
    return [np.asarray(x, np.float64) for x in jax.tree_util.tree_leaves(tree)]


def max_abs(a, b) -> float:
    la, lb = _leaves(a), _leaves(b)
    assert len(la) == len(lb) and all(x.shape == y.shape for x, y in zip(la, lb))
    return max(float(np.max(np.abs(x - y))) for x, y in zip(la, lb))


def max_rel(a, b) -> float:
    """Per tensor max|a - b| / max|b| (b the reference), max over tensors."""
    la, lb = _leaves(a), _leaves(b)
    assert len(la) == len(lb) and all(x.shape == y.shape for x, y in zip(la, lb))
    return max(float(np.max(np.abs(x - y)) / max(np.max(np.abs(y)), 1e-30))
               for x, y in zip(la, lb))


def rel(a, b) -> float:
    a, b = float(np.asarray(a).reshape(-1)[0]), float(np.asarray(b).reshape(-1)[0])
    return abs(a - b) / max(abs(b), 1e-30)


def params_of(state) -> Dict:
    return {n: getattr(state, f"{n}_params") for n in PARAM_NAMES
            if getattr(state, f"{n}_params") is not None}


def log_prob_tolerance(agent, action: np.ndarray, np_dtype) -> np.ndarray:
    """Per sample 1e-6 + 3 ulp(1) * sum_i |d/dy log(scale (1 - y^2) + 1e-6)| at y_i = tanh(u_i):
    the rounding of tanh carried through the epsilon correction, whose derivative
    2 scale y / (scale (1 - y^2) + 1e-6) grows like cosh^2(u). XLA's float32 tanh is within
    4.1 ulp and PyTorch's within 0.56 (docs/equivalence.md), so the two differ by up to about
    4.7 ulp(y); 3 ulp(1) is 6 ulp(y) for |y| >= 1/2, where the derivative is largest. (At
    2 ulp(1) the largest measured difference took 0.61 of the bound, SSE4.2 to AVX-512.)"""
    scale, bias = np.asarray(agent.action_scale, np.float64), np.asarray(agent.action_bias, np.float64)
    y = (np.asarray(action, np.float64) - bias) / scale
    condition = np.sum(2.0 * scale * np.abs(y) / (scale * (1.0 - y ** 2) + 1e-6), axis=-1)
    return 1e-6 + 3.0 * np.finfo(np_dtype).eps * condition


def run_torch(family: str, ref, data, dtype, start: int = 0):
    """`reference_update` over `data` = [(batch, noise)] (updates start + 1, ..), the arrays
    cast to `dtype`."""
    for i, (b, noise) in enumerate(data):
        cast = lambda d: {k: np.asarray(v, np.dtype(dtype)) for k, v in d.items()}
        reference_update(family, ref, cast(b), cast(noise), start + i + 1,
                         {"float32": torch.float32, "float64": torch.float64}[dtype])


# ---------------------------------------------------------------------------- measurement
def measure(family: str, dtype: str = "float32", seed: int = 0) -> Dict[str, float]:
    """All errors of one family (see the module docstring)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # PyTorch's intra-op threads only contend on a small machine
    try:
        return _measure(family, dtype, seed)
    finally:
        torch.set_num_threads(threads)


def _measure(family: str, dtype: str, seed: int) -> Dict[str, float]:
    torch_dtype = {"float32": torch.float32, "float64": torch.float64}[dtype]
    np_dtype = np.dtype(dtype)
    if dtype == "float64" and not jax.config.jax_enable_x64:
        raise RuntimeError("float64 needs JAX_ENABLE_X64=1")
    agent = make_agent(family)
    rng = np.random.default_rng(seed)
    t = lambda x: torch.as_tensor(x, dtype=torch_dtype)
    errors: Dict[str, float] = {}

    # --- actions and log-probabilities with the initial weights
    ref = make_reference(family, torch_dtype)
    state = state_from_reference(agent, ref, np_dtype)
    b = random_batch(rng, family, np_dtype)
    eps = rng.standard_normal((BATCH, agent.action_size)).astype(np_dtype)
    with torch.no_grad():
        a_ref, lp_ref = ref.get_action(t(b["obs"]), t(eps))
    a_jax, lp_jax = jit_sample_action(agent, state.actor_params, jnp.asarray(b["obs"]),
                                      jnp.asarray(eps))
    errors["action"] = max_abs(a_jax, a_ref.numpy())
    errors["log_prob"] = max_abs(lp_jax, lp_ref.numpy())
    errors["log_prob_conditioned"] = float(np.max(
        np.abs(np.asarray(lp_jax, np.float64) - lp_ref.numpy())
        / log_prob_tolerance(agent, a_ref.numpy(), np_dtype)))

    # --- one full update: losses, gradients, parameters after the step
    noise = random_noise(rng, agent, np_dtype)
    step = 1 if agent.config.policy_frequency > 1 else 0  # so that the actor block runs
    state = state.replace(step=jnp.int32(step))
    info = reference_update(family, ref, b, noise, step + 1, torch_dtype)
    jnoise = jax.tree_util.tree_map(jnp.asarray, noise)
    probe = jax_probe(agent, state, jax_batch(b), jnoise)
    as_list = lambda x: x if isinstance(x, list) else [x]
    errors["critic_loss"] = rel(probe["critic_loss"], info["critic_loss"])
    errors["critic_grad"] = max_rel(probe["critic_grad"],
                                    transfer.to_flax({"critic": info["critic_grad"]})["critic"])
    ref_actor_loss, ref_actor_grad = as_list(info["actor_loss"]), as_list(info["actor_grad"])
    assert len(probe["actor_loss"]) == len(ref_actor_loss) == agent.config.policy_frequency
    errors["actor_loss"] = max(rel(x, y) for x, y in zip(probe["actor_loss"], ref_actor_loss))
    errors["actor_grad"] = max(
        max_rel(x, transfer.to_flax({"actor": y})["actor"])
        for x, y in zip(probe["actor_grad"], ref_actor_grad))
    errors["log_pi"] = max(max_abs(x, y.numpy()) for x, y in
                           zip(probe["log_pi"], as_list(info["actor_log_pi"])))
    if agent.config.learn_alpha:
        ref_alpha_loss = as_list(info["alpha_loss"])
        assert len(probe["alpha_loss"]) == len(ref_alpha_loss)
        errors["alpha_loss"] = max(rel(x, y) for x, y in zip(probe["alpha_loss"], ref_alpha_loss))
        errors["alpha_grad"] = max(rel(x, y.numpy()) for x, y in
                                   zip(probe["alpha_grad"], as_list(info["alpha_grad"])))
    if agent.config.variant == "v1":
        errors["value_loss"] = rel(probe["value_loss"], info["value_loss"])
        errors["value_grad"] = max_rel(probe["value_grad"],
                                       transfer.to_flax({"value": info["value_grad"]})["value"])
    new_state, _ = jit_sac_update(agent, state, jax_batch(b), jnoise)
    ref_params = transfer.to_flax(ref.networks())
    errors["step_params"] = max_abs(params_of(new_state), ref_params)
    errors["step_alpha"] = abs(float(new_state.alpha) - reference_alpha(ref))
    errors["step_log_alpha"] = abs(float(new_state.log_alpha) - reference_log_alpha(ref))

    # --- RUN_UPDATES updates from the initial weights on identical batches and noise
    ref = make_reference(family, torch_dtype)
    state = state_from_reference(agent, ref, np_dtype)
    initial = transfer.to_flax(ref.networks())
    data = [(random_batch(rng, family, np_dtype), random_noise(rng, agent, np_dtype))
            for _ in range(RUN_UPDATES)]
    run_params = run_alpha = 0.0
    jax_at = {}
    for i, (b, noise) in enumerate(data):
        reference_update(family, ref, b, noise, i + 1, torch_dtype)
        state, _ = jit_sac_update(agent, state, jax_batch(b),
                                  jax.tree_util.tree_map(jnp.asarray, noise))
        if i + 1 in CHECKPOINTS:
            jax_at[i + 1] = params_of(state)
            run_params = max(run_params, max_rel(jax_at[i + 1], transfer.to_flax(ref.networks())))
            run_alpha = max(run_alpha, rel(state.alpha, reference_alpha(ref)))
    assert int(state.step) == RUN_UPDATES
    errors["run_params"], errors["run_alpha"] = run_params, run_alpha

    if dtype == "float32":
        # Control: the float32 reference against itself in float64 (same initial weights, same
        # data). How far float32 rounding alone carries the reference over the run, and how far
        # sac_jax's float32 run is from that float64 run.
        ref32, ref64 = make_reference(family, torch.float32), make_reference(family, torch.float64)
        transfer.from_flax(ref64.networks(), initial)
        ref64.make_optimizers()
        torch32_vs_64 = jax32_vs_64 = 0.0
        done = 0
        for n in CHECKPOINTS:
            run_torch(family, ref32, data[done:n], "float32", done)
            run_torch(family, ref64, data[done:n], "float64", done)
            done = n
            p64 = transfer.to_flax(ref64.networks())
            torch32_vs_64 = max(torch32_vs_64, max_rel(transfer.to_flax(ref32.networks()), p64))
            jax32_vs_64 = max(jax32_vs_64, max_rel(jax_at[n], p64))
        errors["run_params_torch32_vs_torch64"] = torch32_vs_64
        errors["run_params_jax32_vs_torch64"] = jax32_vs_64
    return errors
