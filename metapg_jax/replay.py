"""Uniform replay buffer as a pytree inside the train state (a ring buffer).

Storage is one preallocated array per ``Transition`` field with a leading
capacity axis; ``add`` writes a batch with a scatter at ``(ptr + i) % capacity``
(in place under ``jit``/``scan``, never a copy of the buffer), ``sample`` draws
indices uniformly with replacement from the filled part.
The choice of an own ring buffer over flashbax is measured and explained in
the README ("Replay buffer").
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


def nbytes(state: ReplayState) -> int:
    """Bytes held by the stored arrays (per seed)."""
    return sum(x.size * x.dtype.itemsize for x in jax.tree.leaves(state.data))
