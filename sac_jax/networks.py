"""Flax networks of SAC: an MLP, the critic ensemble Q_1..Q_N, the value network V and the actor.

Shapes: observations (..., O), actions (..., A); a batch dimension B is optional everywhere.

Every network takes `hidden_dtype`: None computes every layer in the parameters' dtype;
`jnp.bfloat16` computes the hidden layers' products, bias adds and ReLUs in bfloat16 while the
parameters, the output layers (Q, V, mean, log std) and everything downstream stay in the
parameters' dtype. Memory traffic, not arithmetic, bounds the networks of many vmapped seeds on
a GPU, and bfloat16 halves it (`SACConfig.hidden_dtype`, BENCHMARKS.md).
"""

from __future__ import annotations

from typing import Any, Callable, Optional, Sequence, Tuple

import flax.linen as nn
import jax
import jax.numpy as jnp


def _uniform(bound: float) -> Callable:
    def init(key, shape, dtype=jnp.float32):
        return jax.random.uniform(key, shape, dtype, -bound, bound)

    return init


def dense_initializers(initializer: str, fan_in: int, last_layer_init: Optional[float], last: bool):
    """(kernel_init, bias_init) of one Dense layer.

    "flax": lecun-normal kernel, zero bias. "torch": nn.Linear's default, kernel and bias
    U(+-1/sqrt(fan_in)). "xavier": Xavier-uniform kernel, zero bias. `last_layer_init=c`
    overrides an output layer with U(+-c) for kernel and bias.
    """
    if last and last_layer_init is not None:
        return _uniform(last_layer_init), _uniform(last_layer_init)
    if initializer == "torch":
        bound = 1.0 / fan_in ** 0.5
        return _uniform(bound), _uniform(bound)
    if initializer == "xavier":
        return nn.initializers.xavier_uniform(), nn.initializers.zeros
    return nn.initializers.lecun_normal(), nn.initializers.zeros


class MLP(nn.Module):
    """x -> relu(W_1 x + b_1) -> ... -> W_L h + b_L, with layers named `Dense_0..Dense_{L-1}`.

    `output_sizes` lists every layer's width, the last one included; `activate_final` applies
    ReLU after the last layer too (a trunk). Layers followed by a ReLU compute in `hidden_dtype`
    (None: the parameters' dtype); a final linear layer in the parameters' dtype.
    `layer_norm` follows each ReLU by a LayerNorm `LayerNorm_i`, h <- g (h - mean h) /
    sqrt(var h + 1e-6) + b over the layer's width (Brax's `q_network_layer_norm`).
    """

    output_sizes: Sequence[int]
    initializer: str = "flax"
    last_layer_init: Optional[float] = None
    activate_final: bool = False
    hidden_dtype: Optional[Any] = None
    layer_norm: bool = False

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        for i, size in enumerate(self.output_sizes):
            last = i == len(self.output_sizes) - 1
            kernel_init, bias_init = dense_initializers(
                self.initializer, x.shape[-1], self.last_layer_init,
                last and not self.activate_final)
            hidden = not last or self.activate_final
            x = nn.Dense(size, kernel_init=kernel_init, bias_init=bias_init,
                         dtype=self.hidden_dtype if hidden else None, name=f"Dense_{i}")(x)
            if hidden:
                x = nn.relu(x)
                if self.layer_norm:
                    x = nn.LayerNorm(dtype=self.hidden_dtype, name=f"LayerNorm_{i}")(x)
        return x


class CriticEnsemble(nn.Module):
    """Q_1..Q_N(s, a): N independent MLPs on concat(s, a), evaluated as one batched computation.

    Parameters carry a leading axis N (one `nn.vmap` over the critic MLP), so the N critics run as
    one batched matmul per layer; `layer_norm` normalises each hidden layer (`MLP`). The input
    is broadcast to (N, ..., O + A) first: from a shared input the first product comes out
    (..., N, H) for width H, and XLA transposes it to (N, ..., H), an extra pass over the
    activations (H100, 256 vmapped seeds of `fast`: BENCHMARKS.md).
    Returns Q of shape (N, ...) for inputs (..., O) and (..., A).
    """

    hidden_sizes: Sequence[int]
    num_critics: int = 2
    initializer: str = "flax"
    last_layer_init: Optional[float] = None
    hidden_dtype: Optional[Any] = None
    layer_norm: bool = False

    @nn.compact
    def __call__(self, obs: jax.Array, action: jax.Array) -> jax.Array:
        ensemble = nn.vmap(
            MLP,
            variable_axes={"params": 0},
            split_rngs={"params": True},
            in_axes=0,
            out_axes=0,
            axis_size=self.num_critics,
        )
        x = jnp.concatenate([obs, action], axis=-1)
        critics = ensemble(tuple(self.hidden_sizes) + (1,), self.initializer,
                           self.last_layer_init, hidden_dtype=self.hidden_dtype,
                           layer_norm=self.layer_norm, name="critics")
        q = critics(jnp.broadcast_to(x, (self.num_critics,) + x.shape))
        return q[..., 0]


class ValueNetwork(nn.Module):
    """V_psi(s): an MLP to one output. Returns shape (...) for observations (..., O)."""

    hidden_sizes: Sequence[int]
    initializer: str = "flax"
    last_layer_init: Optional[float] = None
    hidden_dtype: Optional[Any] = None

    @nn.compact
    def __call__(self, obs: jax.Array) -> jax.Array:
        v = MLP(tuple(self.hidden_sizes) + (1,), self.initializer, self.last_layer_init,
                hidden_dtype=self.hidden_dtype, name="value")(obs)
        return v[..., 0]


class Actor(nn.Module):
    """Gaussian pre-squash parameters (mu(s), log sigma(s)), each of shape (..., A).

    Either one ReLU trunk with two linear heads `mean` and `log_std` (seeds 000, 002, 003) or two
    separate MLPs `mean_net` and `log_std_net` (seed 001). The raw log-std head output x becomes
    "clip": clip(x, min, max), or "tanh": min + (max - min)(tanh(x) + 1) / 2.
    """

    action_size: int
    hidden_sizes: Sequence[int]
    initializer: str = "flax"
    last_layer_init: Optional[float] = None
    separate_log_std_network: bool = False
    log_std_mode: str = "tanh"
    log_std_min: float = -5.0
    log_std_max: float = 2.0
    hidden_dtype: Optional[Any] = None

    @nn.compact
    def __call__(self, obs: jax.Array) -> Tuple[jax.Array, jax.Array]:
        sizes = tuple(self.hidden_sizes) + (self.action_size,)
        mlp = lambda sizes, **kwargs: MLP(sizes, self.initializer, hidden_dtype=self.hidden_dtype,
                                          **kwargs)
        if self.separate_log_std_network:
            mean = mlp(sizes, last_layer_init=self.last_layer_init, name="mean_net")(obs)
            log_std = mlp(sizes, last_layer_init=self.last_layer_init, name="log_std_net")(obs)
        else:
            h = mlp(tuple(self.hidden_sizes), activate_final=True, name="trunk")(obs)
            head = lambda name: mlp((self.action_size,), last_layer_init=self.last_layer_init,
                                    name=name)(h)
            mean, log_std = head("mean"), head("log_std")
        if self.log_std_mode == "clip":
            log_std = jnp.clip(log_std, self.log_std_min, self.log_std_max)
        else:
            log_std = self.log_std_min + 0.5 * (self.log_std_max - self.log_std_min) * (
                jnp.tanh(log_std) + 1.0)
        return mean, log_std
