"""Replay-buffer micro-benchmark: our ring buffer vs flashbax's item buffer, under jit + vmap.

    python -m experiments.bench_replay [--seeds 8] [--capacity 100000]

One "cycle" = add 100 transitions, then draw 50 minibatches of 64 (the paper
preset's DDPG cycle without the networks). Both buffers run the same scan of
cycles for ``--seeds`` seeds in one compiled program; the script prints
compile time (a cold compile: no persistent compile cache) and the median steady-state time
per cycle over repeats, and records them (every repeat) in ``--json``
(``results/benchmarks/benchmarks_replay.json`` by default: one row per buffer, seeds, capacity and
date; a row measured again on the same date replaces the old one).
flashbax is optional (``pip install flashbax``); without it only ours is timed.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import os
import platform
import time

import jax

from experiments.benchmarks.replay import bench, make_flashbax, make_ours, record


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seeds", type=int, default=8)
    p.add_argument("--capacity", type=int, default=100_000)
    p.add_argument("--cycles", type=int, default=200)
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--json", default=os.path.join("results", "benchmarks", "benchmarks_replay.json"),
                   help="where the measured rows are recorded (default: %(default)s)")
    a = p.parse_args(argv)
    if min(a.seeds, a.cycles, a.repeats) <= 0:
        p.error("--seeds, --cycles and --repeats must be positive")
    if a.capacity < 100:
        p.error(f"--capacity must hold one cycle's 100 added transitions, got {a.capacity}")
    from metapg_jax.host import compile_cache

    compile_cache.enable(None)  # cold compile times, whatever JAX_COMPILATION_CACHE_DIR says
    where = {"measured": time.strftime("%Y-%m-%d"), "jax": jax.__version__, "backend": jax.default_backend(),
             "machine": f"{platform.machine()}, {os.cpu_count()} cores"}
    rows = [{**bench("ring", make_ours, a.seeds, a.capacity, a.cycles, a.repeats), **where}]
    try:
        importlib.import_module("flashbax")  # only whether it is installed: make_flashbax imports it to use it
    except ImportError:
        print("flashbax not installed: only the ring buffer was timed")
    else:
        rows.append({**bench("flashbax", make_flashbax, a.seeds, a.capacity, a.cycles, a.repeats), **where,
                     "flashbax": importlib.metadata.version("flashbax")})
        print(f"flashbax / ring time ratio: {rows[1]['ms_per_cycle'] / rows[0]['ms_per_cycle']:.2f}")
    record(a.json, rows)
    print(f"recorded in {a.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
