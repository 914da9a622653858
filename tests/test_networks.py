"""The networks' `hidden_dtype` (bfloat16 hidden layers with float32 parameters and outputs) and
the critics' `layer_norm`."""

import jax
import jax.extend
import jax.numpy as jnp
import numpy as np

from sac_jax import PRESETS
from sac_jax.networks import MLP
from sac_jax.train import agent_for

OBS = jax.random.normal(jax.random.key(1), (256, 4))
ACTION = jax.random.uniform(jax.random.key(2), (256, 1), minval=-3.0, maxval=3.0)


def dot_dtypes(fn, *args):
    """(operand dtypes, result dtype) of every matrix product `fn(*args)` traces, in order."""
    jaxpr = jax.make_jaxpr(fn)(*args)
    found = []

    def walk(jaxpr):
        for eqn in jaxpr.eqns:
            if eqn.primitive.name == "dot_general":
                found.append(tuple(str(v.aval.dtype) for v in eqn.invars + eqn.outvars))
            for sub in jax.extend.core.jaxprs_in_params(eqn.params):
                walk(sub)

    walk(jaxpr.jaxpr)
    return found


def test_mlp_computes_hidden_layers_in_bfloat16_and_its_output_layer_in_float32():
    mlp = MLP((64, 64, 1), hidden_dtype=jnp.bfloat16)
    params = mlp.init(jax.random.key(0), OBS)
    assert {x.dtype for x in jax.tree_util.tree_leaves(params)} == {jnp.dtype(jnp.float32)}
    assert dot_dtypes(mlp.apply, params, OBS) == [("bfloat16",) * 3, ("bfloat16",) * 3,
                                                  ("float32",) * 3]
    assert mlp.apply(params, OBS).dtype == jnp.float32


def test_bfloat16_agent_has_the_float32_agent_parameters_and_close_outputs():
    """Same initial parameters; Q and the actor's (mu, log sigma) within bfloat16 rounding:
    roundings of relative size 2^-8 through a 4-64-64 network stay under 1.5 % of the output's
    scale (0.3-0.6 % here), and are not zero (the hidden layers did round)."""
    config = PRESETS["fast"]
    (full, _), (half, _) = agent_for(config), agent_for(config.replace(hidden_dtype="bfloat16"))
    state_full, state_half = full.init(jax.random.key(0)), half.init(jax.random.key(0))
    for a, b in zip(jax.tree_util.tree_leaves(state_full), jax.tree_util.tree_leaves(state_half)):
        np.testing.assert_array_equal(a, b)
    outputs = lambda agent, s: (
        agent.critic.apply(s.critic_params, OBS, ACTION),
        *agent.actor.apply(s.actor_params, OBS))
    for want, got in zip(outputs(full, state_full), outputs(half, state_half)):
        assert got.dtype == jnp.float32
        error = np.max(np.abs(np.asarray(got) - np.asarray(want)))
        assert 0 < error <= 0.015 * np.max(np.abs(want)), error


def test_critic_layer_norm_normalises_each_hidden_layer_after_its_relu():
    """With `critic_layer_norm`, each critic's hidden layers are LayerNorm(relu(W h + b)): the
    critic's output equals that computed by hand from its parameters, every critic has its own
    scale and offset, and the actor is untouched."""
    config = PRESETS["fast"].replace(critic_layer_norm=True)
    agent, _ = agent_for(config)
    state = agent.init(jax.random.key(0))
    params = state.critic_params["params"]["critics"]
    assert sorted(params) == ["Dense_0", "Dense_1", "Dense_2", "LayerNorm_0", "LayerNorm_1"]
    assert params["LayerNorm_0"]["scale"].shape == (config.num_critics, 64)
    assert "LayerNorm_0" not in str(jax.tree_util.tree_structure(state.actor_params))

    def by_hand(i):
        h = jnp.concatenate([OBS, ACTION], -1)
        for layer in range(2):
            dense, norm = params[f"Dense_{layer}"], params[f"LayerNorm_{layer}"]
            h = jax.nn.relu(h @ dense["kernel"][i] + dense["bias"][i])
            h = (h - h.mean(-1, keepdims=True)) / jnp.sqrt(h.var(-1, keepdims=True) + 1e-6)
            h = h * norm["scale"][i] + norm["bias"][i]
        return (h @ params["Dense_2"]["kernel"][i] + params["Dense_2"]["bias"][i])[:, 0]

    q = agent.critic.apply(state.critic_params, OBS, ACTION)
    for i in range(config.num_critics):
        np.testing.assert_allclose(q[i], by_hand(i), rtol=1e-5, atol=1e-5)
    plain = agent_for(PRESETS["fast"])[0].init(jax.random.key(0)).critic_params
    assert "LayerNorm" not in str(jax.tree_util.tree_structure(plain))
