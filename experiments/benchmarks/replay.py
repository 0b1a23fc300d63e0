"""The replay-buffer micro-benchmark (``python -m experiments.bench_replay``): our ring buffer and
flashbax's item buffer, each timed over the same scan of add-and-sample cycles under jit + vmap; and
the JSON record of the rows."""

from __future__ import annotations

import json
import os
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
