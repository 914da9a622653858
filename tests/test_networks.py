"""The networks' `hidden_dtype` (bfloat16 hidden layers with float32 parameters and outputs) and
the critics' `layer_norm`."""

import jax
import jax.extend
import jax.numpy as jnp
import numpy as np
import pytest

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


def _dense_layers(state):
    """(path, kernel (..., fan_in, fan_out), bias) of every Dense layer of the actor, the
    critics (a leading axis N) and, for v1, the value network."""
    for field in ("actor_params", "critic_params", "value_params"):
        params = getattr(state, field)
        if params is None:
            continue
        flat = {jax.tree_util.keystr(path): x
                for path, x in jax.tree_util.tree_flatten_with_path(params)[0]}
        for path, kernel in flat.items():
            if path.endswith("['kernel']"):
                yield field + path[:-len("['kernel']")], np.asarray(kernel), np.asarray(
                    flat[path[:-len("['kernel']")] + "['bias']"])


@pytest.mark.parametrize("preset", ["fast", "cleanrl", "pendulum", "v1"])
def test_every_layer_is_drawn_from_its_initializer(preset):
    """Per Dense layer (fan_in x fan_out; these tasks have one action, so the output layers, Q,
    V, mean and log std, are those of width 1): "torch" U(+-1/sqrt(fan_in)) for kernel and
    bias; "xavier" U(+-sqrt(6 / (fan_in + fan_out))) kernels and zero biases; "flax"
    lecun-normal kernels (std 1/sqrt(fan_in)) and zero biases; `last_layer_init=c` U(+-c) for
    an output layer's kernel and bias. A uniform draw of 64 or more values comes within 20 % of
    its bound; the critics are drawn independently."""
    config = PRESETS[preset]
    state = agent_for(config)[0].init(jax.random.key(0))
    layers = list(_dense_layers(state))
    assert len(layers) >= 5, [path for path, _, _ in layers]

    def uniform(x, bound, path):
        assert np.abs(x).max() <= bound * (1 + 1e-6), (path, np.abs(x).max(), bound)
        if x.size >= 64:
            assert np.abs(x).max() >= 0.8 * bound, (path, np.abs(x).max(), bound)

    for path, kernel, bias in layers:
        fan_in, fan_out = kernel.shape[-2:]
        if fan_out == 1 and config.last_layer_init is not None:
            uniform(kernel, config.last_layer_init, path)
            uniform(bias, config.last_layer_init, path)
        elif config.init == "torch":
            uniform(kernel, fan_in ** -0.5, path)
            uniform(bias, fan_in ** -0.5, path)
        elif config.init == "xavier":
            uniform(kernel, (6 / (fan_in + fan_out)) ** 0.5, path)
            assert not bias.any(), path
        else:
            assert config.init == "flax"
            np.testing.assert_allclose(kernel.std(), fan_in ** -0.5, rtol=0.25, err_msg=path)
            assert not bias.any(), path
        if path.startswith("critic_params"):
            assert not np.array_equal(kernel[0], kernel[1]), path
