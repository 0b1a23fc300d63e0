"""Shared data types."""

from __future__ import annotations

from typing import Any

import jax
from flax import struct

Params = Any
PRNGKey = jax.Array


@struct.dataclass
class Transition:
    """One environment step, or a batch of them (leading axes are time/batch).

    ``terminated``: the task ended the episode (no bootstrap from ``next_obs``).
    ``truncated``: the time limit ended it (bootstrap as usual).
    ``next_obs`` is the true next observation, also at the end of an episode.
    """

    obs: jax.Array
    action: jax.Array
    reward: jax.Array
    next_obs: jax.Array
    terminated: jax.Array
    truncated: jax.Array


@struct.dataclass
class EpisodeStats:
    """Per-step episode bookkeeping returned by a rollout (not stored in the buffer)."""

    done: jax.Array            # 1.0 where an episode ended at this step
    episode_return: jax.Array  # return of the episode this step belongs to, so far
    episode_length: jax.Array
