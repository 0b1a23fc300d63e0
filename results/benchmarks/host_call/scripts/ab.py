"""The C engine's host call, before and after, in one process: the programs of both are compiled side by side and
their timed calls alternate (ABBA rounds), so a load that changes over minutes (this 2-core machine is shared)
weighs on both alike.

    python results/benchmarks/host_call/scripts/ab.py --before 7cfd91f --out results/benchmarks/host_call/ab.json

* before: ``envs/host_call.py`` as it was at ``--before`` (read with ``git show``; a JAX primitive lowered through
  JAX's private callback module), swapped into ``envs.mujoco_c`` while its programs are traced;
* after: ``envs/host_call.py`` of the working tree (``jax.pure_callback``).

Rows: the host call alone (a host function that does next to nothing); env stepping alone as ``python -m experiments.bench --env-speed`` times it (8 envs vmapped, a jitted scan of
1,000 uniform-random steps with the training wrappers) per MuJoCo task; and whole training as ``experiments.bench``
times it (Hopper DDPG, paper preset, 8 seeds, 6 cycles of 100 steps per call after the warm-up). Both programs of a
row give the same numbers bit for bit (checked). Run from the repository root.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
import types

sys.path.insert(0, os.getcwd())


def load_before(commit: str) -> types.ModuleType:
    src = subprocess.check_output(["git", "show", f"{commit}:envs/host_call.py"], text=True)
    module = types.ModuleType("host_call_before")
    exec(compile(src, f"{commit}:envs/host_call.py", "exec"), module.__dict__)
    return module


def build(host_call, make):
    """``make()`` (which traces and compiles) with ``host_call`` in ``envs.mujoco_c``."""
    import envs.mujoco_c

    saved = envs.mujoco_c.host_call
    envs.mujoco_c.host_call = host_call
    try:
        return make()
    finally:
        envs.mujoco_c.host_call = saved


def alternate(calls: dict, rounds: int) -> dict:
    """Seconds of each call over ``rounds`` ABBA rounds (each name called twice a round)."""
    import jax

    names, times = list(calls), {k: [] for k in calls}
    for _ in range(rounds):
        for name in names + names[::-1]:
            t = time.perf_counter()
            jax.block_until_ready(calls[name]())
            times[name].append(time.perf_counter() - t)
    return times


def call_row(before, rounds: int, steps: int = 2000) -> dict:
    """The host call alone: a scan of ``steps`` calls on a (8, 80) uint32 batch whose host function only copies
    half of it back (no physics), so the time is the call's own."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from envs import host_call

    def fn(w):
        return np.ascontiguousarray(w[..., :40])

    def make(impl):
        def run(x):
            def step(s, _):
                return jnp.concatenate([jax.vmap(lambda r: impl(fn, r, 40))(s), s[:, 40:]], -1) + 1, None
            return jax.lax.scan(step, x, None, length=steps)[0]

        x = jnp.zeros((8, 80), jnp.uint32)
        f = jax.jit(run).lower(x).compile()
        return lambda: f(x)

    calls = {"before": make(before.host_call), "after": make(host_call.host_call)}
    same = np.array_equal(calls["before"](), calls["after"]())
    return summarise({"row": "the host call alone, 8 x 80 words", "task": "-", "identical": same,
                      "steps_per_call": steps, "calls_per_call": steps}, alternate(calls, rounds))


def env_row(task: str, before, rounds: int, num_envs: int = 8, steps: int = 1000) -> dict:
    import jax
    import jax.numpy as jnp
    import numpy as np

    import envs
    from envs import host_call

    def make():
        env = envs.make(task, physics="mujoco")

        def run(state, key):
            def step(s, k):
                a = jax.random.uniform(k, (num_envs, env.action_size), jnp.float32, -1.0, 1.0)
                s = jax.vmap(env.step)(s, a)
                return s, (s.obs, s.reward, s.pipeline_state)

            return jax.lax.scan(step, state, jax.random.split(key, steps))

        state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), num_envs))
        fn = jax.jit(run).lower(state, jax.random.PRNGKey(1)).compile()
        return lambda: fn(state, jax.random.PRNGKey(1))

    calls = {"before": build(before.host_call, make), "after": build(host_call.host_call, make)}
    outs = {k: jax.device_get(f()) for k, f in calls.items()}
    same = all(np.array_equal(a, b) for a, b in zip(jax.tree.leaves(outs["before"]), jax.tree.leaves(outs["after"])))
    times = alternate(calls, rounds)
    return summarise({"row": f"{task}, env stepping alone, {num_envs} envs", "task": task, "identical": same,
                      "steps_per_call": num_envs * steps, "calls_per_call": steps}, times)


def training_row(before, rounds: int, task: str = "hopper", seeds: int = 8, target_steps: int = 600) -> dict:
    import jax
    import numpy as np

    from envs import host_call
    from metapg_jax.config import make_config
    from metapg_jax.train import make_train, seed_keys, vmap_seeds

    cfg = make_config(task, "ddpg", "paper", physics="mujoco")
    cycles = max(1, target_steps // cfg.steps_per_cycle)
    keys = seed_keys(0, seeds)
    states = {}

    def make(name):
        def go():
            trainer = make_train(cfg)

            def cycles_fn(state):
                return jax.lax.scan(lambda s, _: trainer.cycle(s), state, None, length=cycles)

            state = jax.jit(vmap_seeds(trainer.init))(keys)
            full = jax.jit(vmap_seeds(cycles_fn), donate_argnums=0).lower(state).compile()
            while int(state.env_steps[0]) < max(cfg.run.warmup_steps, cfg.ddpg.batch_size):
                state, _ = full(state)
            states[name] = state

            def call():
                states[name], m = full(states[name])
                return m

            return call
        return go

    calls = {"before": build(before.host_call, make("before")), "after": build(host_call.host_call, make("after"))}
    for f in calls.values():
        f()
    same = all(np.array_equal(a, b) for a, b in zip(jax.tree.leaves(jax.device_get(states["before"])),
                                                    jax.tree.leaves(jax.device_get(states["after"]))))
    times = alternate(calls, rounds)
    return summarise({"row": f"{task} ddpg paper, {seeds} seeds, whole training", "task": task, "identical": same,
                      "steps_per_call": seeds * cycles * cfg.steps_per_cycle,
                      "calls_per_call": cycles * cfg.steps_per_cycle}, times)


def summarise(row: dict, times: dict) -> dict:
    """Env steps/s of each, after / before, and the time added per host call (one per vectorised step:
    ``calls_per_call`` of them in a timed call): from the median call and from the fastest call of each (the
    load of a shared machine only adds time, so the fastest calls are the least disturbed)."""
    med = {k: statistics.median(v) for k, v in times.items()}
    best = {k: min(v) for k, v in times.items()}
    n, calls = row["steps_per_call"], row["calls_per_call"]
    return {**row, "times": times, "before_steps_per_s": n / med["before"], "after_steps_per_s": n / med["after"],
            "after_over_before": med["before"] / med["after"],
            "us_added_per_host_call": 1e6 * (med["after"] - med["before"]) / calls,
            "best_after_over_before": best["before"] / best["after"],
            "best_us_added_per_host_call": 1e6 * (best["after"] - best["before"]) / calls}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--before", required=True, help="the commit whose envs/host_call.py is 'before'")
    p.add_argument("--out", required=True, help="the JSON file to write")
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--tasks", default="inverted_pendulum,inverted_double_pendulum,hopper,halfcheetah,reacher",
                   help="env-stepping rows ('' for none)")
    p.add_argument("--no-training", action="store_true")
    args = p.parse_args()
    import jax

    from metapg_jax.host import compile_cache, provenance

    compile_cache.enable(None)
    before = load_before(args.before)
    meta = {"date": time.strftime("%Y-%m-%d"), "before": args.before, "jax": jax.__version__,
            "machine": f"{platform.machine()}, {os.cpu_count()} cores, {platform.python_version()}",
            "rounds": args.rounds, **{k: v for k, v in provenance.record().items() if k in ("commit", "dirty")}}
    rows = [call_row(before, args.rounds)]
    print(json.dumps({k: v for k, v in rows[-1].items() if k != "times"}), flush=True)
    for task in filter(None, args.tasks.split(",")):
        rows.append(env_row(task, before, args.rounds))
        print(json.dumps({k: v for k, v in rows[-1].items() if k != "times"}), flush=True)
    if not args.no_training:
        rows.append(training_row(before, args.rounds))
        print(json.dumps({k: v for k, v in rows[-1].items() if k != "times"}), flush=True)
    with open(args.out, "w") as f:
        json.dump({"meta": meta, "rows": rows}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
