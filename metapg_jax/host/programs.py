"""Compiled programs kept for the life of the process.

A second run of the same program in one process (an in-process resume, a repeated run, the next run of a notebook's
loop, a sweep's group started again) takes the compiled program the first one built: it neither traces, lowers nor
loads it again (the persistent compile cache, ``compile_cache``, skips XLA's compile only; tracing and lowering a
training program cost 2-20 s on the 2-core CPU machine). The numbers are the same: it is the same executable.

A kept program is found by its key: what the caller says defines it (the config, the input shapes) and what the
process adds here (``key``): the devices, the compile-cache folder (a run that asks for another cache, or none,
compiles: tests of the cache see its loads), the ``METAPG_*`` variables that programs read when they are built (the
C engine's thread count) and JAX's switches that change a program (``jax_debug_nans`` and the like). At most
``KEEP`` programs are kept, the least recently used going first; ``forget`` drops them all.
"""

from __future__ import annotations

import collections
import os
from typing import Any, Callable, Hashable

KEEP = 16
_kept: collections.OrderedDict = collections.OrderedDict()
_FLAGS = ("jax_debug_nans", "jax_debug_infs", "jax_disable_jit", "jax_enable_x64", "jax_default_matmul_precision",
          "jax_numpy_rank_promotion")


def key(*parts: Hashable) -> tuple:
    """The key of a program defined by ``parts``, with what the process adds (the module's docstring)."""
    import jax

    from metapg_jax.host import compile_cache

    variables = tuple(sorted((k, v) for k, v in os.environ.items() if k.startswith("METAPG_")))
    flags = tuple(getattr(jax.config, name, None) for name in _FLAGS)
    return (*parts, tuple(d.id for d in jax.devices()), compile_cache.current(), variables, flags)


def shapes(tree: Any) -> tuple:
    """A pytree's structure and its leaves' shapes and dtypes: the part of a program's key its inputs give."""
    import jax

    leaves, structure = jax.tree_util.tree_flatten(tree)
    return structure, tuple((tuple(x.shape), str(x.dtype)) for x in leaves)


def kept(program_key: tuple, build: Callable[[], Any]) -> tuple[Any, bool]:
    """(the program kept under ``program_key``, True), or (``build()``, False) after keeping it."""
    if program_key in _kept:
        _kept.move_to_end(program_key)
        return _kept[program_key], True
    program = build()
    _kept[program_key] = program
    while len(_kept) > KEEP:
        _kept.popitem(last=False)
    return program, False


def peek(program_key: tuple) -> Any:
    """The program kept under ``program_key``, or None (nothing is built)."""
    return _kept.get(program_key)


def forget() -> None:
    """Drops every kept program (the next run compiles, or loads from the compile cache)."""
    _kept.clear()
