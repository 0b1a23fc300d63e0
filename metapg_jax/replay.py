"""Uniform replay buffer as a pytree inside the train state (a ring buffer).

Storage is one preallocated array per ``Transition`` field with a leading
capacity axis; ``add`` writes a batch with a scatter at ``(ptr + i) % capacity``
(in place under ``jit``/``scan``, never a copy of the buffer), ``sample`` draws
indices uniformly with replacement from the filled part.
The choice of an own ring buffer over flashbax is measured and explained in
docs/performance.md ("Replay buffer").
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

from metapg_jax.types import Transition


@struct.dataclass
class ReplayState:
    data: Transition     # each field (capacity, ...)
    ptr: jax.Array       # int32: next write position
    size: jax.Array      # int32: number of valid entries
    capacity: int = struct.field(pytree_node=False)


def init(capacity: int, obs_size: int, action_size: int) -> ReplayState:
    if capacity <= 0:
        raise ValueError(f"buffer capacity must be positive, got {capacity}")
    f = jnp.float32
    data = Transition(
        obs=jnp.zeros((capacity, obs_size), f),
        action=jnp.zeros((capacity, action_size), f),
        reward=jnp.zeros((capacity,), f),
        next_obs=jnp.zeros((capacity, obs_size), f),
        terminated=jnp.zeros((capacity,), f),
        truncated=jnp.zeros((capacity,), f),
    )
    return ReplayState(data=data, ptr=jnp.zeros((), jnp.int32), size=jnp.zeros((), jnp.int32),
                       capacity=capacity)


def add(state: ReplayState, batch: Transition) -> ReplayState:
    """Appends a batch of transitions with one leading axis (n, ...)."""
    n = batch.reward.shape[0]
    idx = (state.ptr + jnp.arange(n, dtype=jnp.int32)) % state.capacity
    data = jax.tree.map(lambda buf, x: buf.at[idx].set(x.astype(buf.dtype)), state.data, batch)
    return state.replace(
        data=data,
        ptr=(state.ptr + n) % state.capacity,
        size=jnp.minimum(state.size + n, state.capacity),
    )


def sample(state: ReplayState, key: jax.Array, batch_size: int) -> Transition:
    """Uniform minibatch (with replacement) from the filled part of the buffer."""
    idx = jax.random.randint(key, (batch_size,), 0, jnp.maximum(state.size, 1))
    return jax.tree.map(lambda buf: buf[idx], state.data)


def grow(state: ReplayState, capacity: int) -> ReplayState:
    """The same buffer with a larger capacity (zero rows appended), for extending a run's budget.

    Valid only for a buffer that has never overwritten a transition (it holds them in the order they
    came, at rows ``0 .. size-1``): the result then equals the buffer a run with ``capacity`` from the
    start would hold, since ``sample`` draws from the filled part only. Works on one seed's buffer or
    on a seed-batched one (the capacity axis is the leading axis of ``reward`` either way).
    The caller checks that no transition was overwritten; the defaults guarantee it (see
    ``experiments.run``: a capacity grows only when it was the whole, smaller, budget)."""
    old = state.capacity
    if capacity < old:
        raise ValueError(f"cannot shrink a replay buffer from {old} to {capacity}")
    if capacity == old:
        return state
    axis = state.data.reward.ndim - 1  # 0 for one seed, 1 with a leading seed axis

    def pad(x):
        widths = [(0, 0)] * x.ndim
        widths[axis] = (0, capacity - old)
        return jnp.pad(x, widths)

    # Never wrapped: the next row to write is row ``size`` (the old ring had wrapped ``ptr`` to 0
    # when it was exactly full). A new array, not ``size`` itself (a donated state must not alias).
    return ReplayState(data=jax.tree.map(pad, state.data), ptr=state.size % capacity, size=state.size,
                       capacity=capacity)


def nbytes(state: ReplayState) -> int:
    """Bytes held by the stored arrays (per seed)."""
    return sum(x.size * x.dtype.itemsize for x in jax.tree.leaves(state.data))
