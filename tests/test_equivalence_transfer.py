"""Weight transfer torch <-> Flax (references/transfer.py), both directions, for the three
references: a round trip is exact, and the transferred networks compute the same outputs
(actor mean and log std, both critics, the value network) to float32 rounding: a forward pass
is a chain of dot products of at most F = the network's summed fan-ins, so two float32
implementations differ by at most 2 F 2^-24 (Higham's gamma_F, any summation order, FMA or
not) relative to the outputs' scale (`forward_bound`; 3e-5..6e-5 here)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import torch

import sac_jax
from tests.equivalence_harness import FAMILIES, make_agent, make_reference
from references import transfer


def _forward_torch(family, ref, obs, action):
    t = lambda x: torch.as_tensor(x)
    with torch.no_grad():
        if family == "cleanrl":
            mean, log_std = ref.actor(t(obs))
            qs = [ref.qf1(t(obs), t(action)), ref.qf2(t(obs), t(action))]
            v = None
        elif family == "pendulum":
            mean, log_std = ref.policy(t(obs))
            qs = list(ref.critic(t(obs), t(action)))
            v = None
        else:
            mean, log_std = ref.pi_phi(t(obs))
            qs = [ref.Q_theta_1(t(obs), t(action)), ref.Q_theta_2(t(obs), t(action))]
            v = ref.V_psi(t(obs)).view(-1).numpy()
    return mean.numpy(), log_std.numpy(), np.stack([q.view(-1).numpy() for q in qs]), v


def _forward_jax(agent, params, obs, action):
    mean, log_std = agent.actor.apply(params["actor"], obs)
    q = agent.critic.apply(params["critic"], obs, action)
    v = agent.value.apply(params["value"], obs) if "value" in params else None
    return mean, log_std, q, v


def forward_bound(family) -> float:
    """2 F 2^-24 for F = the largest summed fan-ins of the family's networks."""
    preset, obs, act = FAMILIES[family][:3]
    config = sac_jax.PRESETS[preset]
    fan_ins = max(obs + sum(config.actor_hidden), obs + act + sum(config.critic_hidden))
    return 2 * fan_ins * 2.0 ** -24


def _assert_same_outputs(a, b, family):
    """Each output within `forward_bound` of its scale (max(1, max|y|))."""
    for x, y in zip(a, b):
        if y is None:
            assert x is None
            continue
        tol = forward_bound(family) * max(1.0, float(np.max(np.abs(y))))
        np.testing.assert_allclose(np.asarray(x), y, rtol=0, atol=tol)


def _inputs(family, seed=0):
    _, obs, act, low, high, _ = FAMILIES[family]
    rng = np.random.default_rng(seed)
    return (rng.standard_normal((32, obs)).astype(np.float32),
            rng.uniform(low, high, (32, act)).astype(np.float32))


@pytest.mark.parametrize("family", list(FAMILIES))
def test_torch_to_flax(family):
    """Reference weights -> Flax: layouts match `agent.init`'s, outputs agree, and loading the
    Flax trees back into a fresh reference reproduces the weights exactly."""
    ref, agent = make_reference(family), make_agent(family)
    params = transfer.to_flax(ref.networks())
    state = agent.init(jax.random.PRNGKey(0))
    for name, tree in params.items():
        ours = getattr(state, f"{name}_params")
        assert jax.tree_util.tree_structure(ours) == jax.tree_util.tree_structure(tree), name
        for x, y in zip(jax.tree_util.tree_leaves(ours), jax.tree_util.tree_leaves(tree)):
            assert x.shape == y.shape and y.dtype == np.float32, name
    obs, action = _inputs(family)
    jparams = jax.tree_util.tree_map(jnp.asarray, params)
    _assert_same_outputs(_forward_jax(agent, jparams, obs, action),
                         _forward_torch(family, ref, obs, action), family)

    other = make_reference(family)
    with torch.no_grad():  # scramble, so the load must overwrite every weight
        for spec in other.networks().values():
            for p in jax.tree_util.tree_leaves(spec, is_leaf=lambda x: isinstance(x, torch.nn.Linear)):
                p.weight.add_(1.0)
                p.bias.add_(1.0)
    transfer.from_flax(other.networks(), params)
    back = transfer.to_flax(other.networks())
    for x, y in zip(jax.tree_util.tree_leaves(back), jax.tree_util.tree_leaves(params)):
        np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("family", list(FAMILIES))
def test_flax_to_torch(family):
    """`agent.init` weights -> reference: outputs agree, and reading them back gives the Flax
    trees exactly."""
    ref, agent = make_reference(family), make_agent(family)
    state = agent.init(jax.random.PRNGKey(1))
    names = transfer.to_flax(ref.networks()).keys()
    params = {n: getattr(state, f"{n}_params") for n in names}
    transfer.from_flax(ref.networks(), params)
    back = transfer.to_flax(ref.networks())
    for n in names:
        for x, y in zip(jax.tree_util.tree_leaves(back[n]), jax.tree_util.tree_leaves(params[n])):
            np.testing.assert_array_equal(x, np.asarray(y))
    obs, action = _inputs(family, 1)
    _assert_same_outputs(_forward_jax(agent, params, obs, action),
                         _forward_torch(family, ref, obs, action), family)


def test_a_layer_count_or_shape_mismatch_is_refused():
    """Another preset's critic has another depth; a layer whose kernel lost a column has
    another shape: both are refused by name, before a weight is copied."""
    ref = make_reference("cleanrl")
    params = transfer.to_flax(make_reference("pendulum").networks())
    with pytest.raises(ValueError, match="torch layers but .* Flax layers"):
        transfer.from_flax(ref.networks(), {"critic": params["critic"]})
    own = transfer.to_flax(ref.networks())["critic"]
    cut = jax.tree_util.tree_map(lambda x: x, own)  # a copy to cut
    layers = next(iter(cut["params"].values()))
    layers["Dense_0"]["kernel"] = np.asarray(layers["Dense_0"]["kernel"])[:, :-1]
    with pytest.raises(ValueError, match=r"Dense_0: shapes \(\d+, \d+\), \(\d+,\) do not fit"):
        transfer.from_flax(ref.networks(), {"critic": cut})
