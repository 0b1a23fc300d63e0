"""The seed axis: seeds are a ``vmap`` over PRNG keys, and this module names that axis and gives the helpers
that depend on it. Students, explorers and the loop import these from here (and nothing else of each other).

``vmap_seeds`` vmaps with ``axis_name=SEED_AXIS``. The numbers are the same with a plain ``jax.vmap``, but
rare per-seed events (a new parameter-noise perturbation at an episode start, TD3's delayed actor update,
the end of the warm-up) are then computed at every step for every seed (``per_seed_cond``).
"""

from __future__ import annotations

from typing import Any, Callable

import jax
import jax.numpy as jnp

SEED_AXIS = "seeds"


def vmap_seeds(fn, **kwargs):
    """``jax.vmap`` over the seed axis, named ``SEED_AXIS`` (see ``per_seed_cond``)."""
    return jax.vmap(fn, axis_name=SEED_AXIS, **kwargs)


def seed_keys(seed: int, num_seeds: int) -> jax.Array:
    """One key per seed; seed i's key does not depend on how many seeds run."""
    base = jax.random.PRNGKey(seed)
    # fold_in(base, i) for i = 0..num_seeds-1, in one call (a Python loop took ~6 ms a seed).
    return jax.vmap(lambda i: jax.random.fold_in(base, i))(jnp.arange(num_seeds, dtype=jnp.uint32))


def any_over_seeds(flag: jax.Array) -> jax.Array:
    """Whether ``flag`` holds for any seed of the batch: an unbatched predicate for ``lax.cond``.

    Under ``vmap`` a ``lax.cond`` on a per-seed predicate becomes a ``select`` that computes both branches for
    every seed at every call. Outside a ``vmap_seeds`` (one seed, or a plain ``jax.vmap``) the axis is unbound
    and ``flag`` is returned.
    """
    try:
        return jax.lax.pmax(flag.astype(jnp.int32), SEED_AXIS) > 0
    except NameError:  # no vmap named SEED_AXIS around this trace
        return flag


def per_seed_cond(flag: jax.Array, new: Callable[[Any], Any], old: Callable[[Any], Any], operand: Any) -> Any:
    """``new(operand)`` where this seed's ``flag`` holds, else ``old(operand)``; ``new`` runs only when some seed
    of the batch needs it.

    ``lax.cond(any_over_seeds(flag), where(flag, new, old), old)``: the same values as
    ``where(flag, new(operand), old(operand))`` (both pytrees of the same structure), at the cost of ``old``
    alone on the calls where no seed's flag holds.
    """
    return jax.lax.cond(any_over_seeds(flag),
                        lambda x: jax.tree.map(lambda a, b: jnp.where(flag, a, b), new(x), old(x)), old, operand)
