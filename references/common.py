"""Small helpers shared by the references (no algorithmic content)."""

from __future__ import annotations

from types import SimpleNamespace

import torch
import torch.nn as nn


def grads(layers):
    """The current gradients of a nested dict/list of `nn.Linear` layers, in the same layout:
    each layer becomes an object with `.weight` and `.bias` holding copies of their gradients
    (zeros where there is none), so references/transfer.py reads them like weights."""
    if isinstance(layers, dict):
        return {k: grads(v) for k, v in layers.items()}
    if isinstance(layers, (list, tuple)):
        return [grads(v) for v in layers]
    assert isinstance(layers, nn.Linear)
    g = lambda p: (p.grad if p.grad is not None else torch.zeros_like(p)).detach().clone()
    return SimpleNamespace(weight=g(layers.weight), bias=g(layers.bias))
