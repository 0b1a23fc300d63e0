"""The host call under the C engine's envs (``envs/mujoco_c.py``, ``envs/gym_generic.py``): a JAX primitive whose
lowering is XLA's Python callback, the float32 <-> uint32 word views of the state the envs carry, and the thread
count of MuJoCo's batch.

The primitive skips ``jax.pure_callback``'s detour (pure_callback device_puts every argument into a jax Array
before calling the function and converts the result back; a HalfCheetah step of 8 envs cost 169 us on top of the
physics with it, 59 us with this). The function gets and returns numpy arrays; under vmap the batch axis is moved
to the front, so one call gets the whole seeds x envs batch. Pure: no effects, so XLA may drop or repeat it like
any op.
"""

from __future__ import annotations

import os

import jax
import jax.numpy as jnp
import numpy as np
from jax._src import callback as _callback_lib  # private: the jax<0.11 pin covers it
from jax.extend.core import Primitive
from jax.interpreters import batching, mlir

__all__ = ["default_threads", "host_call"]


def default_threads() -> int:
    """MuJoCo threads per batch: the CPUs this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


_host_call_p = Primitive("mujoco_c_host_call")


def host_call(fn, words: jax.Array, width: int) -> jax.Array:
    """``fn(words) -> out`` on the host: uint32 (..., w_in) -> uint32 (..., width), numpy to numpy."""
    return _host_call_p.bind(words, fn=fn, width=int(width))


@_host_call_p.def_impl
def _host_call_impl(words, *, fn, width):
    return jnp.asarray(fn(np.asarray(words)))


@_host_call_p.def_abstract_eval
def _host_call_abstract(words, *, fn, width):
    return jax.core.ShapedArray(words.shape[:-1] + (width,), jnp.uint32)


def _host_call_batch(args, dims, *, fn, width):
    (words,), (dim,) = args, dims
    if dim is None:  # not mapped (JAX's batching.not_mapped)
        return host_call(fn, words, width), None
    return host_call(fn, jnp.moveaxis(words, dim, 0), width), 0


def _host_call_lowering(ctx, words, *, fn, width):
    (aval_out,) = ctx.avals_out
    sharding = _callback_lib._callback_op_sharding(ctx.module_context.axis_context, None, ctx.avals_out)

    def call(w):
        return (fn(w),)

    result, _, _ = _callback_lib.emit_python_callback(
        ctx, call, None, [words], ctx.avals_in, [aval_out], has_side_effect=False, sharding=sharding)
    return result


batching.primitive_batchers[_host_call_p] = _host_call_batch
mlir.register_lowering(_host_call_p, _host_call_lowering)


def _words(x: jax.Array) -> jax.Array:
    """float32 (..., k) -> uint32 (..., k), the same bits."""
    return jax.lax.bitcast_convert_type(jnp.asarray(x, jnp.float32), jnp.uint32)


def _floats(w: jax.Array) -> jax.Array:
    return jax.lax.bitcast_convert_type(w, jnp.float32)
