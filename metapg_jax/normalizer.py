"""Running mean / std of observations, as the 2018 OpenAI-baselines DDPG.

Baselines' ``RunningMeanStd`` starts from count 1e-2, mean 0 and sum of squares
1e-2, updates with exact batch moments, and uses std = sqrt(max(var, 1e-2));
normalised observations are clipped to +-5 (``obs_clip``).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct


@struct.dataclass
class NormalizerState:
    count: jax.Array   # float32 scalar
    sum: jax.Array     # (obs_size,)
    sumsq: jax.Array   # (obs_size,)


_EPS = 1e-2


def init(obs_size: int) -> NormalizerState:
    return NormalizerState(
        count=jnp.asarray(_EPS, jnp.float32),
        sum=jnp.zeros((obs_size,), jnp.float32),
        sumsq=jnp.full((obs_size,), _EPS, jnp.float32),
    )


def update(state: NormalizerState, obs: jax.Array) -> NormalizerState:
    """Adds a batch of observations, shape (..., obs_size)."""
    flat = obs.reshape(-1, obs.shape[-1]).astype(jnp.float32)
    return NormalizerState(
        count=state.count + flat.shape[0],
        sum=state.sum + flat.sum(0),
        sumsq=state.sumsq + jnp.square(flat).sum(0),
    )


def mean_std(state: NormalizerState) -> tuple[jax.Array, jax.Array]:
    """Mean and std; works with leading (e.g. seed) axes, where ``count`` has one entry per row."""
    count = state.count[..., None]
    mean = state.sum / count
    var = jnp.maximum(state.sumsq / count - jnp.square(mean), _EPS)
    return mean, jnp.sqrt(var)


def normalize(state: NormalizerState | None, obs: jax.Array, clip: float) -> jax.Array:
    """(obs - mean) / std clipped to [-clip, clip]; identity when ``state`` is None."""
    if state is None:
        return obs
    mean, std = mean_std(state)
    return jnp.clip((obs - mean) / std, -clip, clip)
