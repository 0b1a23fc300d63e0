"""A bounded sample of visited states, for the state-visitation figure (paper Figure 4).

Per seed it keeps the first ``k`` and the latest ``k`` observations of the
exploring policy (the teacher's D0, or the DDPG baseline's noisy actor) and of
the student (D1, the look-ahead student's rollouts), mirroring the paper's
"first 50 roll-outs" vs "last 50 roll-outs" panels.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct


@struct.dataclass
class VisitState:
    explore_early: jax.Array   # (k, obs) first k states of the exploring policy
    explore_late: jax.Array    # (k, obs) ring of its latest k states
    student_early: jax.Array
    student_late: jax.Array
    explore_count: jax.Array   # int32: states seen so far
    student_count: jax.Array


def init(k: int, obs_size: int) -> VisitState:
    z = jnp.zeros((k, obs_size), jnp.float32)
    c = jnp.zeros((), jnp.int32)
    return VisitState(z, z, z, z, c, c)


def _record(early, late, count, obs):
    k = early.shape[0]
    n = obs.shape[0]
    idx = count + jnp.arange(n, dtype=jnp.int32)
    # Early: write only while the first k are not full (out-of-range writes are dropped).
    early = early.at[jnp.where(idx < k, idx, k)].set(obs, mode="drop")
    late = late.at[idx % k].set(obs)
    return early, late, count + n


def record(state: VisitState, explore_obs: jax.Array | None = None,
           student_obs: jax.Array | None = None) -> VisitState:
    """Adds flat batches (n, obs) of states of the exploring policy and/or the student."""
    if explore_obs is not None:
        e, l, c = _record(state.explore_early, state.explore_late, state.explore_count, explore_obs)
        state = state.replace(explore_early=e, explore_late=l, explore_count=c)
    if student_obs is not None:
        e, l, c = _record(state.student_early, state.student_late, state.student_count, student_obs)
        state = state.replace(student_early=e, student_late=l, student_count=c)
    return state
