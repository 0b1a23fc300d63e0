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
import json
import os
import platform
import statistics
import time

import jax
import jax.numpy as jnp

from metapg_jax import replay
from metapg_jax.types import Transition


def _batch(key, n, obs_size, act_size):
    k1, k2 = jax.random.split(key)
    return Transition(obs=jax.random.normal(k1, (n, obs_size)), action=jax.random.uniform(k2, (n, act_size)),
                      reward=jnp.ones((n,)), next_obs=jax.random.normal(k2, (n, obs_size)),
                      terminated=jnp.zeros((n,)), truncated=jnp.zeros((n,)))


def make_ours(capacity, obs_size, act_size, batch_size):
    def init(key):
        return replay.init(capacity, obs_size, act_size)

    def cycle(state, key):
        k_add, k_s = jax.random.split(key)
        state = replay.add(state, _batch(k_add, 100, obs_size, act_size))
        samples = jax.vmap(lambda k: replay.sample(state, k, batch_size).reward.sum())(jax.random.split(k_s, 50))
        return state, samples.sum()

    return init, cycle


def make_flashbax(capacity, obs_size, act_size, batch_size):
    import flashbax as fbx

    buf = fbx.make_item_buffer(max_length=capacity, min_length=1, sample_batch_size=batch_size,
                               add_sequences=True)

    def init(key):
        item = jax.tree.map(lambda x: x[0], _batch(key, 1, obs_size, act_size))
        return buf.init(item)

    def cycle(state, key):
        k_add, k_s = jax.random.split(key)
        state = buf.add(state, _batch(k_add, 100, obs_size, act_size))
        samples = jax.vmap(lambda k: buf.sample(state, k).experience.reward.sum())(jax.random.split(k_s, 50))
        return state, samples.sum()

    return init, cycle


def bench(name, factory, seeds, capacity, cycles, repeats):
    init, cycle = factory(capacity, 9, 1, 64)

    def run(state, key):
        return jax.lax.scan(cycle, state, jax.random.split(key, cycles))

    keys = jax.random.split(jax.random.PRNGKey(0), seeds)
    state = jax.jit(jax.vmap(init))(keys)
    t0 = time.perf_counter()
    fn = jax.jit(jax.vmap(run), donate_argnums=0).lower(state, keys).compile()
    compile_s = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        state, out = fn(state, keys)
        jax.block_until_ready(out)
        times.append(time.perf_counter() - t)
    per_cycle_ms = 1e3 * statistics.median(times) / cycles
    print(f"{name:10s} seeds={seeds} capacity={capacity:,}: compile {compile_s:.2f} s, "
          f"{per_cycle_ms:.3f} ms per cycle (add 100 + 50 x sample 64), median of {repeats}")
    return {"buffer": name, "seeds": seeds, "capacity": capacity, "cycles": cycles, "repeats": repeats,
            "compile_s": compile_s, "ms_per_cycle": per_cycle_ms, "times_s": times}


def record(path: str, rows: list[dict]) -> None:
    """Adds ``rows`` to the JSON record at ``path`` (atomically), replacing rows of the same buffer,
    seeds, capacity and date."""
    from metapg_jax.host import runfiles

    old = []
    if os.path.exists(path):
        with open(path) as f:
            old = json.load(f)["rows"]
    key = lambda r: (r["buffer"], r["seeds"], r["capacity"], r["measured"])
    new = {key(r) for r in rows}
    runfiles.write_json_atomic(path, {"rows": [r for r in old if key(r) not in new] + rows})


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
        import flashbax  # noqa: F401
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
