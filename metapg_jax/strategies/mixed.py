"""Per-episode noise scales (FastTD3, Seo et al., 2025): ``--noise=mixed`` for ``--method=ddpg``.

Each seed's exploring env draws its Gaussian noise scale sigma ~ U[min_stddev, max_stddev] at every episode
start and keeps it for the episode: a = clip(mu(s) + sigma * N(0, I)). Defaults are FastTD3's
(``std_min = 0.001``, ``std_max = 0.4``). FastTD3 draws one scale per parallel env and redraws it when that
env's episode ends; here each seed has one exploring env, so the scale changes from episode to episode rather
than across envs. Not a sampling noise for a stochastic student (its point is the scale, which SAC learns).
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp

from metapg_jax import action_noise, strategy


@dataclasses.dataclass(frozen=True)
class MixedConfig:
    """The range of the per-episode noise scale (the ``mixed`` group)."""

    min_stddev: float = 0.001   # FastTD3's std_min
    max_stddev: float = 0.4     # FastTD3's std_max


def _init(config, action_size: int) -> jax.Array:
    """The scale, repeated per action dimension (which carries the action's shape); replaced at the first
    episode's first step."""
    m = config.mixed
    return jnp.full((action_size,), 0.5 * (m.min_stddev + m.max_stddev), jnp.float32)


def _episode_start(config, stddev: jax.Array, key: jax.Array) -> jax.Array:
    m = config.mixed
    return jnp.full_like(stddev, jax.random.uniform(key, (), jnp.float32, m.min_stddev, m.max_stddev))


def _sample(config, stddev: jax.Array, key: jax.Array):
    return jax.random.normal(key, stddev.shape), stddev, stddev


def _validate(config) -> None:
    m = config.mixed
    if not (math.isfinite(m.min_stddev) and math.isfinite(m.max_stddev) and 0 <= m.min_stddev <= m.max_stddev):
        raise ValueError(f"mixed.min_stddev and mixed.max_stddev must be finite with 0 <= min <= max, got "
                         f"{m.min_stddev!r} and {m.max_stddev!r}")


NAME = "mixed"
strategy.register_group(NAME, MixedConfig)
action_noise.register_kind(action_noise.NoiseKind(
    NAME, _init, _sample, episode_start=_episode_start, validate=_validate,
    metrics=lambda config, stddev: {"noise_scale": stddev[0]},
    summary="Gaussian noise whose scale ~ U[min, max] is redrawn at every episode start (FastTD3)"))
