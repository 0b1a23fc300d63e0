"""The host call under the C engine's envs (``envs/mujoco_c.py``, ``envs/gym_generic.py``): ``jax.pure_callback``
with ``vmap_method="expand_dims"``, the float32 <-> uint32 word views of the state the envs carry, and the thread
count of MuJoCo's batch.

Everything here is public JAX API (nothing from JAX's private package; ``tests/test_imports.py`` checks the repository
for it).
Under ``vmap`` the callback is not looped: each vmap adds a leading batch axis to its one argument, so one call
gets the whole seeds x envs batch. Under ``jit`` with the seed axis sharded over several devices (automatic
sharding, as ``experiments.run`` does it) JAX runs the callback once, on the first device, with the whole batch
(tests/test_physics.py). It needs JAX's CPU backend (on a GPU, ``JAX_PLATFORMS`` must list ``cpu``). Pure: no effects, so XLA may drop or repeat it like any op.

What it costs: ``pure_callback`` device_puts its argument into a jax Array before calling the function, a fixed
cost per call, so the call passes one packed array each way: it is paid once per env step, not per field. Against
the primitive on JAX's private callback module used before 2026-12-06 (which handed the function XLA's numpy
arrays), a call costs about 95 us more (about 103 us against 8 us), and more inside the env programs on a loaded
machine: env stepping of 8 envs 0.50-0.95x as fast, 8-seed Hopper DDPG training 0.86-1.03x
(``results/benchmarks/host_call/``; docs/performance.md). An XLA FFI handler (``jax.ffi``) would skip the
device_put, but needs compiled code: a handler that calls back into Python, or the task math in C++.
"""

from __future__ import annotations

import os

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["THREADS_VARIABLE", "default_threads", "host_call", "resolve_threads"]


# What ``--physics-threads`` sets (experiments.run, experiments.sweep, the grid commands): the C engine's threads per
# batch for every env this process builds without an explicit count.
THREADS_VARIABLE = "METAPG_PHYSICS_THREADS"


def default_threads() -> int:
    """MuJoCo threads per batch when none is given: ``$METAPG_PHYSICS_THREADS`` if set, else the CPUs this
    process may run on. ``ValueError`` (one line) for a bad value of the variable."""
    value = os.environ.get(THREADS_VARIABLE, "").strip()
    if value:
        return resolve_threads(value, f"{THREADS_VARIABLE}=")
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def resolve_threads(threads, what: str = "physics threads ") -> int:
    """A thread count (an int >= 1, or its digits) or None (``default_threads``); ``ValueError`` (one line)
    otherwise. The count changes no number (each env steps on its own), only the speed."""
    if threads is None:
        return default_threads()
    try:
        n = int(threads)
    except (TypeError, ValueError):
        n = 0
    if isinstance(threads, bool) or n < 1 or str(n) != str(threads).strip():
        raise ValueError(f"{what}must be a whole number >= 1, got {threads!r}")
    return n


def host_call(fn, words: jax.Array, width: int) -> jax.Array:
    """``fn(words) -> out`` on the host: uint32 (..., w_in) -> uint32 (..., width), numpy to numpy.

    Under ``vmap`` the batch axes come first (``vmap_method="expand_dims"``): ``fn`` sees (*batch, ..., w_in)."""
    words = jnp.asarray(words)
    if words.dtype != jnp.uint32 or words.ndim < 1:
        raise TypeError(f"host_call takes uint32 words (..., w), got {words.dtype} {words.shape}")
    out = jax.ShapeDtypeStruct(words.shape[:-1] + (int(width),), jnp.uint32)
    return jax.pure_callback(_Numpy(fn), out, words, vmap_method="expand_dims")


class _Numpy:
    """``fn`` on numpy arrays (``pure_callback`` hands its function jax Arrays on the CPU; ``np.asarray`` is
    a view of one, no copy). Equal for equal ``fn``, so JAX's caches see the same callback."""

    __slots__ = ("fn",)

    def __init__(self, fn):
        self.fn = fn

    def __call__(self, words):
        return self.fn(np.asarray(words))

    def __eq__(self, other):
        return isinstance(other, _Numpy) and self.fn == other.fn

    def __hash__(self):
        return hash(self.fn)


def _words(x: jax.Array) -> jax.Array:
    """float32 (..., k) -> uint32 (..., k), the same bits."""
    return jax.lax.bitcast_convert_type(jnp.asarray(x, jnp.float32), jnp.uint32)


def _floats(w: jax.Array) -> jax.Array:
    return jax.lax.bitcast_convert_type(w, jnp.float32)
