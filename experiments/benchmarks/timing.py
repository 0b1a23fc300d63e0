"""The clock every benchmark reads: the median wall time of a compiled call after one warm call."""

from __future__ import annotations

import statistics
import time


def _timed(fn, args, repeats: int):
    """Median wall time of ``fn(*args)`` over ``repeats`` calls after one warm call; all times."""
    import jax

    jax.block_until_ready(fn(*args))
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - t)
    return statistics.median(times), times

