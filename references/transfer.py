"""Weight transfer between the references' `nn.Linear` layers and sac_jax's Flax parameters.

A reference's `networks()` names its layers in sac_jax's layout:
    "actor":   {"trunk": [..], "mean": [..], "log_std": [..]} or {"mean_net": [..], "log_std_net": [..]}
    "critic", "critic_target": [[layers of Q_1], [layers of Q_2]]
    "value", "value_target": [layers of V]
and the Flax trees are
    actor   {'params': {name: {'Dense_i': {'kernel': (in, out), 'bias': (out,)}}}}
    critic  {'params': {'critics': {'Dense_i': {'kernel': (N, in, out), 'bias': (N, out)}}}}
    value   {'params': {'value': {'Dense_i': ...}}}
A Flax kernel (in, out) is the transpose of the torch weight (out, in); critic i of the
ensemble is the i-th entry of the leading axis. Values move as numpy arrays of the tensors'
dtype, unchanged (no arithmetic), so a round trip is exact.
"""

from __future__ import annotations

from typing import Dict, List

import numpy as np
import torch

KINDS = {"actor": "actor", "critic": "critic", "critic_target": "critic", "value": "value",
         "value_target": "value"}


def _np(t) -> np.ndarray:
    return t.detach().cpu().numpy().copy()


def mlp_to_flax(layers: List) -> Dict:
    """[Linear_0, .., Linear_{L-1}] -> {'Dense_i': {'kernel': W_i^T, 'bias': b_i}}. Any object
    with `.weight` and `.bias` tensors works (e.g. the gradients of references/common)."""
    return {f"Dense_{i}": {"kernel": _np(l.weight).T.copy(), "bias": _np(l.bias)}
            for i, l in enumerate(layers)}


def network_to_flax(kind: str, spec) -> Dict:
    if kind == "actor":
        return {"params": {name: mlp_to_flax(layers) for name, layers in spec.items()}}
    if kind == "critic":
        members = [mlp_to_flax(layers) for layers in spec]
        stacked = {d: {k: np.stack([m[d][k] for m in members]) for k in ("kernel", "bias")}
                   for d in members[0]}
        return {"params": {"critics": stacked}}
    if kind == "value":
        return {"params": {"value": mlp_to_flax(spec)}}
    raise ValueError(kind)


def to_flax(networks: Dict) -> Dict:
    """A reference's `networks()` (or gradients in that layout) -> {name: Flax params}."""
    return {name: network_to_flax(KINDS[name], spec) for name, spec in networks.items()}


def _load_mlp(layers: List, tree: Dict) -> None:
    if len(layers) != len(tree):
        raise ValueError(f"{len(layers)} torch layers but {len(tree)} Flax layers")
    with torch.no_grad():
        for i, layer in enumerate(layers):
            kernel = np.asarray(tree[f"Dense_{i}"]["kernel"])
            bias = np.asarray(tree[f"Dense_{i}"]["bias"])
            if kernel.T.shape != tuple(layer.weight.shape) or bias.shape != tuple(layer.bias.shape):
                raise ValueError(f"Dense_{i}: shapes {kernel.shape}, {bias.shape} do not fit "
                                 f"{tuple(layer.weight.shape)}, {tuple(layer.bias.shape)}")
            layer.weight.copy_(torch.as_tensor(kernel.T.copy(), dtype=layer.weight.dtype))
            layer.bias.copy_(torch.as_tensor(bias.copy(), dtype=layer.bias.dtype))


def network_from_flax(kind: str, spec, params: Dict) -> None:
    """Copies Flax `params` into the torch layers of `spec`, in place."""
    p = params["params"]
    if kind == "actor":
        if set(p) != set(spec):
            raise ValueError(f"actor parts {sorted(p)} vs {sorted(spec)}")
        for name, layers in spec.items():
            _load_mlp(layers, p[name])
    elif kind == "critic":
        critics = p["critics"]
        for i, layers in enumerate(spec):
            _load_mlp(layers, {d: {k: np.asarray(v)[i] for k, v in leaf.items()}
                               for d, leaf in critics.items()})
    elif kind == "value":
        _load_mlp(spec, p["value"])
    else:
        raise ValueError(kind)


def from_flax(networks: Dict, params: Dict) -> None:
    """Loads {name: Flax params} into a reference's `networks()`, in place (names absent from
    `params` are left alone)."""
    for name, spec in networks.items():
        if name in params and params[name] is not None:
            network_from_flax(KINDS[name], spec, params[name])
