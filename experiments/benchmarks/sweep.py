"""The sweep benchmark (``python -m experiments.bench --sweep``): a 32-setting sweep as one program vs
the 32 separate runs it replaces; and its table."""

from __future__ import annotations

import time

from experiments.benchmarks.timing import _timed


SWEEP_GRID = {"meta.lr": [3e-5, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 1e-1], "meta.init_log_std": [-1.5, -1.0, -0.5, 0.0]}


def measure_sweep(task: str = "pendulum", seeds: int = 1, repeats: int = 3, chunk_steps: int = 3000) -> dict:
    """A 32-setting sweep (``SWEEP_GRID``: 8 teacher learning rates x 4 initial log-stds, Meta, paper preset)
    as one program (``metapg_jax.sweep``) against the 32 separate runs it replaces, in this process:
    cold compile of each program (separately), and the median time of one evaluation chunk of
    ``chunk_steps`` env steps per seed after a warm call."""
    import itertools

    import jax
    import jax.numpy as jnp

    import envs
    from metapg_jax.config import make_config, override
    from metapg_jax.seeds import seed_keys, vmap_seeds
    from metapg_jax.sweep import Sweep
    from metapg_jax.train import make_train

    cfg = make_config(task, "meta", steps=3 * chunk_steps, overrides={"run.eval_every": chunk_steps})
    settings = [override(cfg, dict(zip(SWEEP_GRID, v))) for v in itertools.product(*SWEEP_GRID.values())]
    env = envs.make(cfg.env.name, source=cfg.env.source, episode_length=cfg.episode_length, physics=cfg.env.physics)
    sweep = Sweep(cfg, env, tuple(SWEEP_GRID))
    values = jnp.repeat(sweep.values(settings), seeds, axis=0)
    keys = jnp.concatenate([seed_keys(0, seeds)] * len(settings))

    def time_program(init, chunk, args):
        state = jax.jit(init)(*args)
        t = time.perf_counter()
        compiled = jax.jit(chunk).lower(state, *args[1:]).compile()
        compile_s = time.perf_counter() - t
        run_chunk = lambda st: compiled(st, *args[1:])
        median, times = _timed(run_chunk, (state,), repeats)
        return compile_s, median, times

    sweep_compile, sweep_chunk, sweep_times = time_program(vmap_seeds(sweep.init), vmap_seeds(sweep.train_chunk),
                                                           (keys, values))
    trainer = make_train(settings[-1], env)
    one_compile, one_chunk, one_times = time_program(lambda k: vmap_seeds(trainer.init)(k),
                                                     lambda st: vmap_seeds(trainer.train_chunk)(st),
                                                     (seed_keys(0, seeds),))
    n = len(settings)
    return {"date": time.strftime("%Y-%m-%d"), "task": task, "method": "meta", "preset": "paper",
            "settings": n, "seeds_per_setting": seeds, "chunk_env_steps_per_seed": chunk_steps,
            "grid": SWEEP_GRID, "sweep_compile_s": round(sweep_compile, 2), "run_compile_s": round(one_compile, 2),
            "sweep_chunk_s": sweep_chunk, "run_chunk_s": one_chunk, "sweep_chunk_times": sweep_times,
            "run_chunk_times": one_times,
            "sweep_steps_per_s": n * seeds * chunk_steps / sweep_chunk,
            "separate_steps_per_s": seeds * chunk_steps / one_chunk,
            # steady state: the 32 runs one after another vs the sweep; end to end: each separate run compiles
            "steady_ratio": n * one_chunk / sweep_chunk,
            "one_run_of_each_chunk_ratio": (n * (one_compile + one_chunk)) / (sweep_compile + sweep_chunk)}


def sweep_markdown(r: dict, meta: dict) -> str:
    return "\n".join([
        f"## A sweep as one program vs separate runs ({r['date']}, {meta['machine']}, JAX {meta['jax']}, "
        f"{meta['backend']})", "",
        f"`python -m experiments.bench --sweep`: {r['settings']} settings (Meta on {r['task']}, paper preset; "
        f"{', '.join(f'`{k}`' for k in r['grid'])}: {' x '.join(str(len(v)) for v in r['grid'].values())}) x "
        f"{r['seeds_per_setting']} seed(s), one evaluation chunk of {r['chunk_env_steps_per_seed']:,} env steps per "
        f"seed, median of {meta['repeats']} after a warm call; cold compiles. Raw numbers: `{meta['json']}`.", "",
        "| | compile (s) | one chunk (s) | env steps/s total |", "|---|---|---|---|",
        f"| sweep: {r['settings']} settings in one program | {r['sweep_compile_s']:.1f} | {r['sweep_chunk_s']:.2f} | "
        f"{r['sweep_steps_per_s']:,.0f} |",
        f"| one separate run (of {r['settings']}) | {r['run_compile_s']:.1f} | {r['run_chunk_s']:.2f} | "
        f"{r['separate_steps_per_s']:,.0f} |", "",
        f"Steady state, the sweep does the work of the {r['settings']} separate runs {r['steady_ratio']:.1f}x faster "
        f"({r['settings']} x one run's chunk / the sweep's chunk); with one chunk each and every separate run "
        f"compiling afresh, {r['one_run_of_each_chunk_ratio']:.1f}x."])

