"""Actor, critic and teacher networks (flax.linen).

Student networks follow the 2018 OpenAI-baselines DDPG (``baselines/ddpg/models.py``),
which the paper's implementation is built on: hidden layers Dense -> LayerNorm
-> ReLU with Glorot-uniform kernels and zero biases, the critic takes the
action at its second layer, the last layers are U(-3e-3, 3e-3), the actor ends
in tanh. ``layer_norm=False`` and ``action_layer=0`` give the modern variant.

Module names are fixed (``dense_i``, ``ln_i``, ``out``) because adaptive
parameter noise perturbs every parameter except the LayerNorm ones, and the
critic's L2 penalty applies to hidden kernels only (as baselines).
"""

from __future__ import annotations

from typing import Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp


def _uniform(scale: float):
    def init(key, shape, dtype=jnp.float32):
        return jax.random.uniform(key, shape, dtype, -scale, scale)

    return init


class Actor(nn.Module):
    """Deterministic policy mu(s) in [-1, 1]^action_size."""

    action_size: int
    hidden: Sequence[int] = (64, 64)
    layer_norm: bool = True
    final_init: float = 3e-3

    @nn.compact
    def __call__(self, obs: jax.Array) -> jax.Array:
        x = obs
        for i, width in enumerate(self.hidden):
            x = nn.Dense(width, kernel_init=nn.initializers.glorot_uniform(), name=f"dense_{i}")(x)
            if self.layer_norm:
                x = nn.LayerNorm(name=f"ln_{i}")(x)
            x = nn.relu(x)
        x = nn.Dense(self.action_size, kernel_init=_uniform(self.final_init), name="out")(x)
        return jnp.tanh(x)


class Critic(nn.Module):
    """Q(s, a). The action is concatenated to the input of hidden layer ``action_layer``."""

    hidden: Sequence[int] = (64, 64)
    layer_norm: bool = True
    action_layer: int = 1
    final_init: float = 3e-3

    @nn.compact
    def __call__(self, obs: jax.Array, action: jax.Array) -> jax.Array:
        x = obs
        for i, width in enumerate(self.hidden):
            if i == self.action_layer:
                x = jnp.concatenate([x, action], axis=-1)
            x = nn.Dense(width, kernel_init=nn.initializers.glorot_uniform(), name=f"dense_{i}")(x)
            if self.layer_norm:
                x = nn.LayerNorm(name=f"ln_{i}")(x)
            x = nn.relu(x)
        x = nn.Dense(1, kernel_init=_uniform(self.final_init), name="out")(x)
        return x[..., 0]


class MLP(nn.Module):
    """A plain MLP head (no output squashing): the teacher's mean and log-std networks.

    Same hidden layers as the student (Dense -> LayerNorm -> ReLU) and the same
    small uniform last layer; ``bias_init`` sets the initial output (used to
    start the teacher's log-std at ``init_log_std``).
    """

    out_size: int
    hidden: Sequence[int] = (64, 64)
    layer_norm: bool = True
    final_init: float = 3e-3
    bias_init: float = 0.0

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        for i, width in enumerate(self.hidden):
            x = nn.Dense(width, kernel_init=nn.initializers.glorot_uniform(), name=f"dense_{i}")(x)
            if self.layer_norm:
                x = nn.LayerNorm(name=f"ln_{i}")(x)
            x = nn.relu(x)
        return nn.Dense(self.out_size, kernel_init=_uniform(self.final_init),
                        bias_init=nn.initializers.constant(self.bias_init), name="out")(x)


def is_layer_norm_path(path) -> bool:
    """True for parameters that live in a LayerNorm module (name contains 'ln_')."""
    return any("ln_" in str(getattr(p, "key", p)) for p in path)


def is_hidden_kernel_path(path) -> bool:
    """True for kernels of hidden Dense layers (not LayerNorm, not the output layer)."""
    names = [str(getattr(p, "key", p)) for p in path]
    return names[-1] == "kernel" and any(n.startswith("dense_") or "_dense_" in n for n in names)
