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


class GaussianMLP(nn.Module):
    """Mean and log-std MLPs of a diagonal Gaussian policy (the paper's teacher, section 5.1).

    Two separate 64-64 MLPs, as the paper: one for the mean, one for the log
    standard deviation. The mean is not squashed; the sample is clipped to the
    action bounds only for the environment. Log-std is bounded to
    [min_log_std, max_log_std] with a tanh-free soft clip (see ``teacher.py``).
    """

    action_size: int
    hidden: Sequence[int] = (64, 64)
    layer_norm: bool = True
    final_init: float = 3e-3
    init_log_std: float = 0.0

    @nn.compact
    def __call__(self, obs: jax.Array) -> tuple[jax.Array, jax.Array]:
        def trunk(x, prefix):
            for i, width in enumerate(self.hidden):
                x = nn.Dense(width, kernel_init=nn.initializers.glorot_uniform(), name=f"{prefix}_dense_{i}")(x)
                if self.layer_norm:
                    x = nn.LayerNorm(name=f"{prefix}_ln_{i}")(x)
                x = nn.relu(x)
            return x

        mean = nn.Dense(self.action_size, kernel_init=_uniform(self.final_init), name="mean_out")(trunk(obs, "mean"))
        log_std = nn.Dense(
            self.action_size,
            kernel_init=_uniform(self.final_init),
            bias_init=nn.initializers.constant(self.init_log_std),
            name="log_std_out",
        )(trunk(obs, "log_std"))
        return mean, log_std


def is_layer_norm_path(path) -> bool:
    """True for parameters that live in a LayerNorm module (name contains 'ln_')."""
    return any("ln_" in str(getattr(p, "key", p)) for p in path)


def is_hidden_kernel_path(path) -> bool:
    """True for kernels of hidden Dense layers (not LayerNorm, not the output layer)."""
    names = [str(getattr(p, "key", p)) for p in path]
    return names[-1] == "kernel" and any(n.startswith("dense_") or "_dense_" in n for n in names)
