"""Where every second goes: whole training vs environment stepping alone vs DDPG updates alone.

    python -m experiments.bench                       # the default grid (tens of minutes on 2 CPU cores)
    python -m experiments.bench --envs pendulum --seeds 1,8 --repeats 5
    python -m experiments.bench --quick               # pendulum only, 1 and 8 seeds
    python -m experiments.bench --envs hopper,halfcheetah --physics mjx,mujoco --presets paper --seeds 8
    python -m experiments.bench --env-speed           # env stepping alone: MJX, the C engine, its limits
    python -m experiments.bench --sweep               # a 32-setting sweep as one program vs 32 separate runs
    python -m experiments.bench --main-job            # the README's main job: cold compile, first 60k steps

For every (task, method, preset, seeds) it runs a fresh subprocess (so peak
memory and compile caches are its own) that measures, in one process:

* compile time of the training program (``lower().compile()``), separately, always a cold
  compile (the persistent compile cache ``experiments.run`` uses is off here);
* whole training (``cycles`` scanned cycles, vmapped over seeds; no evaluation):
  median over ``--repeats`` timed calls after one warm call -> env steps/s;
* the two parts alone, with the same step and update counts and the same seed
  batch: environment stepping alone (a scan of the same number of env steps,
  uniform random actions, same wrappers), and the same number of DDPG updates
  alone (minibatches from the filled buffer; Meta also counts its look-ahead
  updates);
* the **overhead ratio** = full training time / (env-alone + updates-alone);
* one evaluation (``eval_episodes`` episodes) separately: its cost is not in
  the training numbers;
* peak RSS of the subprocess, its growth over the RSS after imports, and the
  replay buffers' own bytes.

The **seed-scaling ratio** (total throughput at 8 seeds / at 1 seed) is
computed across rows. Results go to ``results/benchmarks/BENCHMARKS.md`` (tables) and a
JSON file beside it (raw numbers, every repeat). Timings on shared machines vary: compare ratios
measured in one run, never single timings across runs.
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

BENCH_DIR = "results/benchmarks"  # where the records go by default (relative to the repository root)
TARGETS = {"overhead": 1.2, "scaling_8": 2.5, "compile_s": 60.0, "rss_over_buffer": 2.0,
           "main_job_compile_s": 30.0}  # the README's main job on its default engine, cold, on a 2-core CPU
MAIN_JOB = ["--env=inverted_double_pendulum", "--seeds=8"]  # the README's first command


def _rss_mib() -> float:
    """Current resident set size (MiB) from /proc (Linux); peak from getrusage."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return float("nan")


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


def measure_one(spec: dict) -> dict:
    """All measurements for one configuration, in this process."""
    import jax
    import jax.numpy as jnp

    from metapg_jax import replay
    from metapg_jax.host import terminal
    from metapg_jax.config import make_config
    from metapg_jax.rollout import rollout
    from metapg_jax.loop import train_updates
    from metapg_jax.train import make_train, seed_keys, vmap_seeds

    rss_base = _rss_mib()
    overrides = dict(spec.get("overrides", {}))
    cfg = make_config(spec["env"], spec["method"], spec["preset"], overrides=overrides,
                      physics=spec.get("physics", "mjx"))
    env = None
    if spec.get("stock_mjx"):  # MJX's own (scanned) line search instead of our early exit, for before/after
        import envs

        env = envs.make(cfg.env.name, source=cfg.env.source, episode_length=cfg.episode_length,
                        early_exit_linesearch=False)
    trainer = make_train(cfg, env)
    seeds, repeats = spec["seeds"], spec["repeats"]
    cycles = max(1, spec["target_steps"] // cfg.steps_per_cycle)
    keys = seed_keys(0, seeds)
    updates_per_cycle = cfg.run.train_steps + (
        (cfg.meta.lookahead_steps or cfg.run.train_steps) if cfg.run.method == "meta" else 0)

    # -- whole training (cycles only) -------------------------------------------------------
    def cycles_fn(state):
        return jax.lax.scan(lambda s, _: trainer.cycle(s), state, None, length=cycles)

    state = jax.jit(vmap_seeds(trainer.init))(keys)
    t = time.perf_counter()
    # plain_vmap: an unnamed seed axis, so episode-start branches run for every seed at every step
    # (the numbers are the same; see metapg_jax.seeds.per_seed_cond): the 'before' of that change.
    seed_vmap = jax.vmap if spec.get("plain_vmap") else vmap_seeds
    full = jax.jit(seed_vmap(cycles_fn), donate_argnums=0).lower(state).compile()
    compile_s = time.perf_counter() - t
    # Warm-up: fill the buffer past the warm-up phase so every timed call does real updates.
    while int(state.env_steps[0]) < max(cfg.run.warmup_steps, cfg.ddpg.batch_size):
        state, _ = full(state)
    state, _ = full(state)
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        state, m = full(state)
        jax.block_until_ready(m)
        times.append(time.perf_counter() - t)
    full_s = statistics.median(times)
    steps = seeds * cycles * cfg.steps_per_cycle

    # -- environment stepping alone: same steps, same batch ------------------------------------
    env = trainer.env

    def random_policy(carry, obs, first, k):
        return jax.random.uniform(k, (env.action_size,), jnp.float32, -1.0, 1.0), carry, None

    def env_only(env_state, key):
        def one_cycle(s, k):
            s, _, tr, _, _ = rollout(env, random_policy, s, None, k, cfg.steps_per_cycle)
            return s, tr.reward.sum()

        return jax.lax.scan(one_cycle, env_state, jax.random.split(key, cycles))

    env_fn = jax.jit(jax.vmap(env_only))
    env_s, env_times = _timed(env_fn, (state.env_state, keys), repeats)

    # -- the same number of DDPG updates alone, on the filled buffer ---------------------------
    learner = trainer.student

    def updates_only(st, key):
        sample = lambda k: replay.sample(st.buffer, k, cfg.ddpg.batch_size)
        student, metrics = train_updates(learner, st.student, st.normalizer, sample, key,
                                            cycles * updates_per_cycle)
        return student, metrics

    upd_fn = jax.jit(jax.vmap(updates_only))
    upd_s, upd_times = _timed(upd_fn, (state, keys), repeats)

    # -- one evaluation ---------------------------------------------------------------------------
    eval_fn = jax.jit(jax.vmap(trainer.evaluate))
    eval_s, eval_times = _timed(eval_fn, (state, keys), max(1, repeats // 2))

    buffer_mib = seeds * replay.nbytes(jax.tree.map(lambda x: x[0], state.buffer)) / 2**20
    peak = terminal.peak_rss_mib()
    return {
        **{k: spec[k] for k in ("env", "method", "preset", "seeds")}, "stock_mjx": bool(spec.get("stock_mjx")),
        "physics": cfg.env.physics,
        "plain_vmap": bool(spec.get("plain_vmap")), "measured": time.strftime("%Y-%m-%d"),
        "backend": jax.default_backend(), "device": str(jax.devices()[0]),
        "cycles": cycles, "steps_per_cycle": cfg.steps_per_cycle, "updates_per_cycle": updates_per_cycle,
        "env_steps_measured": steps, "compile_s": compile_s,
        "full_s": full_s, "full_times": times, "env_s": env_s, "env_times": env_times,
        "updates_s": upd_s, "update_times": upd_times, "eval_s": eval_s, "eval_times": eval_times,
        "eval_episodes": cfg.run.eval_episodes,
        "steps_per_s_total": steps / full_s, "steps_per_s_per_seed": steps / full_s / seeds,
        "env_alone_steps_per_s": steps / env_s, "updates_alone_per_s": seeds * cycles * updates_per_cycle / upd_s,
        "overhead_ratio": full_s / (env_s + upd_s),
        "buffer_mib": buffer_mib, "peak_rss_mib": peak, "rss_growth_mib": peak - rss_base,
    }


def _c_loops(task: str, num_envs: int, steps: int, threads: int, repeats: int) -> dict:
    """MuJoCo's C engine stepping ``num_envs`` simulations of the task's gymnasium model outside
    JAX: the limits the C engine inside the program is measured against, and the mechanisms it
    could have used. Uniform random controls over ctrlrange, no resets; steps/s (median of repeats).

    * ``raw_loop``: ``mj_step(nstep=frame_skip)`` over one ``MjData`` per env, one Python thread;
    * ``batch``: ``mujoco.batch.Batch`` (``threads`` threads), one ``step`` call per env step (what
      ``envs/mujoco_c.py`` uses);
    * ``rollout``: ``mujoco.rollout.Rollout`` (persistent pool of ``threads``), one call per env step
      from the state rows (it returns states and sensors only, not the warm start or the derived
      fields gymnasium's observations read);
    * ``pool``: one ``MjData`` per env and a Python ``ThreadPoolExecutor`` of ``threads`` (mj_step
      releases the GIL), the envs split into ``threads`` slices.
    """
    from concurrent.futures import ThreadPoolExecutor

    import mujoco
    import numpy as np
    from mujoco import batch as mj_batch
    from mujoco import rollout as mj_rollout

    from envs.gym_mujoco import GYMNASIUM_TASKS

    task_env = GYMNASIUM_TASKS[task]()
    model, fs = task_env.mj_model, task_env.frame_skip
    low, high = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    ctrl = np.random.default_rng(0).uniform(low, high, (steps, num_envs, model.nu))

    def median_rate(run):
        times = []
        for _ in range(repeats):
            t = time.perf_counter()
            run()
            times.append(time.perf_counter() - t)
        return num_envs * steps / statistics.median(times)

    datas = [mujoco.MjData(model) for _ in range(num_envs)]

    def raw():
        for d in datas:
            mujoco.mj_resetData(model, d)
        for k in range(steps):
            for d, u in zip(datas, ctrl[k]):
                d.ctrl[:] = u
                mujoco.mj_step(model, d, nstep=fs)

    b = mj_batch.Batch(model, num_envs, nthread=min(threads, num_envs))
    for name in task_env.derived_fields:
        b.bind(name)
    b_ctrl = b.bind("ctrl")

    def batch():
        b.reset()
        for k in range(steps):
            b_ctrl[:] = ctrl[k]
            b.step(nstep=fs)

    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    roll_datas = [mujoco.MjData(model) for _ in range(max(1, threads))]
    state0 = np.zeros((num_envs, mujoco.mj_stateSize(model, spec)))
    mujoco.mj_getState(model, datas[0], state0[0], spec)
    state0[:] = state0[0]

    def roll(pool):
        state = state0.copy()
        for k in range(steps):
            out, _ = pool.rollout(model, roll_datas, state, np.repeat(ctrl[k][:, None], fs, 1), nstep=fs)
            state = out[:, -1]

    def rollout():
        with mj_rollout.Rollout(nthread=threads) as pool:
            roll(pool)

    slices = np.array_split(np.arange(num_envs), max(1, threads))

    def pooled():
        for d in datas:
            mujoco.mj_resetData(model, d)

        def part(ids, k):
            for i in ids:
                datas[i].ctrl[:] = ctrl[k, i]
                mujoco.mj_step(model, datas[i], nstep=fs)

        with ThreadPoolExecutor(len(slices)) as ex:
            for k in range(steps):
                list(ex.map(part, slices, [k] * len(slices)))

    return {"raw_loop_steps_per_s": median_rate(raw), "batch_steps_per_s": median_rate(batch),
            "rollout_steps_per_s": median_rate(rollout), "pool_steps_per_s": median_rate(pooled),
            "c_threads": threads}


def measure_env_speed(task: str, num_envs: int = 8, steps: int = 1000, repeats: int = 3,
                      stock_mjx: bool = False) -> dict:
    """Env stepping alone, ``num_envs`` envs: our task through the compiled program (a jitted scan,
    vmapped, with the training wrappers, auto-reset included) on each engine: MJX and MuJoCo's C
    engine through the host callback (``physics='mujoco'``); for the MuJoCo tasks the C engine's
    loops outside JAX (``_c_loops``); and gymnasium's own env stepped one at a time in a Python loop.

    With ``stock_mjx``, MJX is timed a second time with its stock line search
    (``early_exit_linesearch=False``) and the two trajectories are checked to be identical
    (see envs/gym_mujoco.py, "Speed")."""
    import gymnasium
    import jax
    import jax.numpy as jnp
    import numpy as np

    import envs
    from envs.mujoco_c import default_threads

    def time_ours(**overrides):
        env = envs.make(task, **overrides)

        def run(state, key):
            def step(s, k):
                a = jax.random.uniform(k, (num_envs, env.action_size), jnp.float32, -1.0, 1.0)
                s = jax.vmap(env.step)(s, a)
                return s, (s.obs, s.reward)

            return jax.lax.scan(step, state, jax.random.split(key, steps))

        t = time.perf_counter()
        state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), num_envs))
        fn = jax.jit(run).lower(state, jax.random.PRNGKey(1)).compile()
        compile_s = time.perf_counter() - t
        seconds, times = _timed(fn, (state, jax.random.PRNGKey(1)), repeats)
        traj = jax.device_get(fn(state, jax.random.PRNGKey(1))[1])
        return num_envs * steps / seconds, times, compile_s, traj

    ours, ours_times, compile_s, traj = time_ours()
    out = {"task": task, "num_envs": num_envs, "steps": steps, "compile_s": compile_s,
           "ours_steps_per_s": ours, "ours_times": ours_times}
    if task != "pendulum":
        threads = default_threads()
        c, c_times, c_compile_s, _ = time_ours(physics="mujoco")
        out.update(c_steps_per_s=c, c_times=c_times, c_compile_s=c_compile_s, c_over_mjx=c / ours,
                   **_c_loops(task, num_envs, steps, threads, repeats))
        out["c_over_raw_loop"] = c / out["raw_loop_steps_per_s"]
        out["c_over_batch"] = c / out["batch_steps_per_s"]
        # What one step of the batch costs in the program on top of the same physics outside JAX: the
        # host call, the task math in numpy, the resets, the wrappers' and the program's own work.
        out["c_overhead_us_per_step"] = 1e6 * num_envs * (1 / c - 1 / out["batch_steps_per_s"])
        if stock_mjx:
            stock, stock_times, stock_compile_s, stock_traj = time_ours(early_exit_linesearch=False)
            out.update(stock_steps_per_s=stock, stock_times=stock_times, stock_compile_s=stock_compile_s,
                       early_exit_speedup=ours / stock,
                       identical_to_stock=all(np.array_equal(a, b) for a, b in zip(traj, stock_traj)))

    genv = gymnasium.make(envs.get_spec(task).gym_id)
    genv.reset(seed=0)
    rng = np.random.default_rng(0)
    low, high = genv.action_space.low, genv.action_space.high
    n = 3000
    t = time.perf_counter()
    for _ in range(n):
        _, _, term, trunc, _ = genv.step(rng.uniform(low, high).astype(np.float32))
        if term or trunc:
            genv.reset()
    out["gymnasium_steps_per_s"] = n / (time.perf_counter() - t)
    return out


ENV_SPEED_TARGETS = {"c_over_mjx": {"hopper": 5.0, "halfcheetah": 5.0, "inverted_double_pendulum": 1.5},
                     "c_over_raw_loop": 0.8}


def env_speed_markdown(results: list[dict], meta: dict) -> str:
    def f(r, k, fmt="{:,.0f}"):
        return fmt.format(r[k]) if k in r else "–"

    def verdict(r):
        want = ENV_SPEED_TARGETS["c_over_mjx"].get(r["task"])
        if "c_over_mjx" not in r:
            return "–"
        ok = [r["c_over_raw_loop"] >= ENV_SPEED_TARGETS["c_over_raw_loop"]] + (
            [r["c_over_mjx"] >= want] if want else [])
        return "yes" if all(ok) else "NO"

    n = results[0]["num_envs"]
    threads = next((r["c_threads"] for r in results if "c_threads" in r), None)
    lines = [
        f"`python -m experiments.bench --env-speed` on {meta['date']} ({meta['machine']}; jax {meta['jax']}, "
        f"backend {meta['backend']}; medians of {meta['repeats']} timed repeats; raw numbers: "
        f"`{os.path.basename(meta['json'])}`), all in one process per run: our tasks, {n} envs vmapped in a "
        f"jitted scan of {results[0]['steps']:,} uniform-random steps with the training wrappers (auto-reset "
        "included), on MJX and on MuJoCo's C engine through the host callback (`--physics=mujoco`"
        + (f", {threads} threads" if threads else "") + "). Then the C engine outside JAX on the same model, "
        f"{n} simulations, random controls, no resets: a plain loop of `mj_step` over one `MjData` each "
        "(one thread: the 'raw loop'), `mujoco.batch.Batch` (what the callback uses), `mujoco.rollout` and "
        "our own `MjData` loop on a Python thread pool (both with the same threads); the program's cost per step "
        f"is the C engine's time per step of the {n} envs in the program minus the batch's outside it (the host "
        "call, the task math in numpy, resets, wrappers). Last, gymnasium's own "
        "env stepped one at a time in a Python loop. Targets: C engine >= "
        f"{ENV_SPEED_TARGETS['c_over_raw_loop']}x the raw loop on every task, and >= 5x MJX on Hopper and "
        "HalfCheetah, >= 1.5x on IDP.", "",
        f"| task | MJX, steps/s | C engine in the program, steps/s | C / MJX | raw C loop | C / raw loop | "
        "batch outside JAX | program's cost per step, us | rollout module | own thread pool | targets met | "
        "gymnasium, 1 env | compile s, MJX / C |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        lines.append(
            f"| {r['task']} | {f(r, 'ours_steps_per_s')} | {f(r, 'c_steps_per_s')} | {f(r, 'c_over_mjx', '{:.2f}x')} | "
            f"{f(r, 'raw_loop_steps_per_s')} | {f(r, 'c_over_raw_loop', '{:.2f}x')} | {f(r, 'batch_steps_per_s')} | "
            f"{f(r, 'c_overhead_us_per_step')} | {f(r, 'rollout_steps_per_s')} | {f(r, 'pool_steps_per_s')} | {verdict(r)} | "
            f"{f(r, 'gymnasium_steps_per_s')} | {f(r, 'compile_s', '{:.1f}')} / {f(r, 'c_compile_s', '{:.1f}')} |")
    if any("stock_steps_per_s" in r for r in results):
        lines += ["", "| task | stock MJX line search, steps/s | early-exit speedup | identical |", "|---|---|---|---|"]
        for r in results:
            if "stock_steps_per_s" in r:
                ident = {True: "yes", False: "NO"}.get(r.get("identical_to_stock"), "–")
                lines.append(f"| {r['task']} | {f(r, 'stock_steps_per_s')} | {f(r, 'early_exit_speedup', '{:.2f}x')} "
                             f"| {ident} |")
    return "\n".join(lines)


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


def measure_main_job(physics: str, steps: int) -> dict:
    """The README's main job (``MAIN_JOB``) run as a user runs it, in a fresh subprocess, cut at ``steps``
    env steps per seed: its cold compile (no persistent compile cache) and its env steps/s over those
    steps (all seeds, evaluations included), from the run's own summary.json. ``physics``: the
    ``--physics`` value ('default' passes none: the command exactly as the README gives it)."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "run")
        argv = [sys.executable, "-m", "experiments.run", *MAIN_JOB, f"--steps={steps}", "--compile-cache=off",
                "--quiet", "--no-plot", f"--out={out}"] + ([] if physics == "default" else [f"--physics={physics}"])
        t = time.perf_counter()
        res = subprocess.run(argv, capture_output=True, text=True)
        wall = time.perf_counter() - t
        if res.returncode != 0:
            raise RuntimeError(f"main job ({physics}) failed: {res.stderr[-2000:]}")
        with open(os.path.join(out, "summary.json")) as f:
            summary = json.load(f)
    return {"physics_flag": physics, "physics": summary["physics"], "steps_per_seed": steps,
            "seeds": summary["num_seeds"], "compile_s": summary["compile_seconds"],
            "train_s": summary["train_seconds"], "steps_per_s_total": summary["env_steps_per_second_total"],
            "wall_s": round(wall, 1), "peak_rss_mib": summary["peak_rss_mib"]}


def main_job_markdown(rows: list[dict], meta: dict) -> str:
    target = TARGETS["main_job_compile_s"]
    commit = f", commit {meta['commit'][:7]}{' (dirty)' if meta.get('dirty') else ''}" if meta.get("commit") else ""
    lines = [f"## The main job ({meta['date']}, {meta['machine']}, JAX {meta['jax']}, {meta['backend']}{commit})", "",
             f"`python -m experiments.bench --main-job`: `python -m experiments.run {' '.join(MAIN_JOB)}` in a fresh "
             f"process with no compile cache, cut at {rows[0]['steps_per_seed']:,} env steps per seed; one run per "
             f"engine, one after the other. Compile: the cold compile the run prints; rate: env steps per second over "
             f"all seeds (evaluations included) from its summary.json. Target: the default engine compiles in "
             f"<= {target:.0f} s on a 2-core CPU. Raw numbers: `{meta['json']}`.", "",
             "| --physics | engine | compile (s) | env steps/s total | train (s) | whole command (s) | peak RSS (MiB) |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['physics_flag']} | {r['physics']} | {r['compile_s']:.1f} | {r['steps_per_s_total']:,.0f} | "
                     f"{r['train_s']:.1f} | {r['wall_s']:.1f} | {r['peak_rss_mib']:,.0f} |")
    default = next((r for r in rows if r["physics_flag"] == "default"), None)
    if default is not None:
        verdict = "met" if default["compile_s"] <= target else "missed"
        lines += ["", f"Default engine ({default['physics']}): compile {default['compile_s']:.1f} s, target {verdict}."]
        mjx = next((r for r in rows if r["physics"] == "mjx" and r is not default), None)
        if mjx is not None and default["physics"] != "mjx":
            lines.append(f"Against MJX in the same run: compile {mjx['compile_s'] / default['compile_s']:.1f}x faster, "
                         f"training {default['steps_per_s_total'] / mjx['steps_per_s_total']:.1f}x faster.")
    return "\n".join(lines)


def write_section(path: str, name: str, text: str) -> None:
    """Replaces the generated section ``name`` of ``path`` (between marker comments), keeping
    everything else in the file (the hand-written analysis); appends it if it is not there."""
    begin, end = f"<!-- bench:{name} (generated) -->", f"<!-- /bench:{name} -->"
    old = open(path).read() if os.path.exists(path) else "# Benchmarks\n"
    block = f"{begin}\n{text.rstrip()}\n{end}"
    if begin in old and end in old:
        new = old[:old.index(begin)] + block + old[old.index(end) + len(end):]
    else:
        new = old.rstrip() + "\n\n" + block + "\n"
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        fh.write(new)
    os.replace(tmp, path)


def _date(r: dict) -> str:
    return r.get("measured", "undated")


def _variant(r: dict) -> str:
    return (" (MuJoCo C)" if r.get("physics") == "mujoco" else "") + (
        " (stock MJX line search)" if r.get("stock_mjx") else "") + (" (plain vmap)" if r.get("plain_vmap") else "")


def _row_md(r: dict, scaling: float | None) -> str:
    def f(x, fmt="{:,.0f}"):
        return "–" if x is None else fmt.format(x)

    env = r["env"] + _variant(r)
    return (f"| {env} | {r['method']} | {r['preset']} | {_date(r)} | {r['seeds']} | {f(r['compile_s'], '{:.1f}')} | "
            f"{f(r['steps_per_s_total'])} | {f(r['steps_per_s_per_seed'])} | {f(r['env_alone_steps_per_s'])} | "
            f"{f(r['updates_alone_per_s'])} | {f(r['overhead_ratio'], '{:.2f}')} | {f(scaling, '{:.2f}')} | "
            f"{f(r['eval_s'], '{:.2f}')} | {f(r['buffer_mib'])} | {f(r['rss_growth_mib'])} | "
            f"{f(r['peak_rss_mib'])} |")


def seed_scaling(rows: list[dict]) -> dict:
    """Total throughput at n seeds / at 1 seed, per (env, method, preset)."""
    group = lambda r: (r["env"], r["method"], r["preset"], _variant(r), _date(r))  # ratios within one date
    base = {group(r): r["steps_per_s_total"] for r in rows if r["seeds"] == 1}
    return {id(r): r["steps_per_s_total"] / base[group(r)] for r in rows if group(r) in base}


def write_markdown(rows: list[dict], path: str, meta: dict) -> None:
    scaling = seed_scaling(rows)
    dates = sorted({_date(r) for r in rows})
    rows = sorted(rows, key=lambda r: (r["env"] != "pendulum", r["env"], r["preset"], r["method"], _date(r),
                                       _variant(r), r["seeds"]))
    lines = [
        f"`python -m experiments.bench`, rows measured on {', '.join(dates)} ({meta['machine']}; jax {meta['jax']}, "
        f"backend {meta['backend']}; {meta['repeats']} timed repeats per number, medians). Raw numbers, every "
        f"repeat: `{os.path.basename(meta['json'])}`.", "",
        "Columns: steady-state env steps/s of whole training (cycles only, evaluation excluded) in total and per "
        "seed; env stepping alone and DDPG updates alone with the same counts and seed batch; overhead = full / "
        "(env alone + updates alone); scaling = total throughput / the 1-seed row's; one evaluation "
        "(`eval_episodes` full episodes) in seconds; replay buffers' bytes; peak RSS growth over the process "
        "after imports, and peak RSS.", "",
        f"Targets: overhead <= {TARGETS['overhead']}, 8-seed scaling >= {TARGETS['scaling_8']}x, compile <= "
        f"{TARGETS['compile_s']:.0f} s, peak memory <= {TARGETS['rss_over_buffer']}x the buffers' bytes.", "",
        "| task | method | preset | measured | seeds | compile s | steps/s total | steps/s per seed | env alone steps/s | "
        "updates alone /s | overhead | scaling | eval s | buffers MiB | RSS growth MiB | peak RSS MiB |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    lines += [_row_md(r, scaling.get(id(r))) for r in rows]
    if len(dates) > 1:
        lines += ["", "Rows of different dates may have run under different machine load: compare ratios "
                  "within a date; scaling is computed within a date."]
    lines += engines_markdown(rows)
    write_section(path, "training", "\n".join(lines))


ENGINE_TARGETS = {"speedup": 4.0, "speedup_tasks": ("hopper", "halfcheetah"), "updates_share": 0.85,
                  "c_compile_s": 30.0}


def engines_markdown(rows: list[dict]) -> list[str]:
    """The two engines side by side, from rows measured on the same date: training throughput with
    MuJoCo's C engine over MJX's; for the C rows, the share of full training time that the DDPG updates
    alone take (1 = physics and bookkeeping cost nothing on top of the updates) and the cold compile."""
    key = lambda r: (r["env"], r["method"], r["preset"], r["seeds"], _date(r))
    mjx = {key(r): r for r in rows if r.get("physics", "mjx") == "mjx" and not r.get("stock_mjx")
           and not r.get("plain_vmap") and r["env"] != "pendulum"}
    c_rows = [r for r in rows if r.get("physics") == "mujoco"]
    if not c_rows:
        return []
    t = ENGINE_TARGETS
    out = ["", f"Engines side by side (rows of the same date): C engine total steps/s over MJX's (target >= "
           f"{t['speedup']:.0f}x on {' and '.join(t['speedup_tasks'])} at 8 seeds, paper preset); updates share "
           f"= updates-alone time / full training time (target >= {t['updates_share']} for the modern preset at 1 "
           f"seed on Hopper); the C engine's cold compile (target <= {t['c_compile_s']:.0f} s).", "",
           "| task | method | preset | seeds | measured | MJX steps/s | C steps/s | C / MJX | updates share | "
           "compile s, MJX / C |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in sorted(c_rows, key=lambda r: (r["env"], r["preset"], r["method"], r["seeds"])):
        m = mjx.get(key(r))
        ratio = f"{r['steps_per_s_total'] / m['steps_per_s_total']:.2f}x" if m else "–"
        out.append(f"| {r['env']} | {r['method']} | {r['preset']} | {r['seeds']} | {_date(r)} | "
                   f"{m and format(m['steps_per_s_total'], ',.0f') or '–'} | {r['steps_per_s_total']:,.0f} | {ratio} | "
                   f"{r['updates_s'] / r['full_s']:.2f} | {m and format(m['compile_s'], '.1f') or '–'} / "
                   f"{r['compile_s']:.1f} |")
    return out


def _cold_compiles() -> None:
    """Compile times here are cold compiles: no persistent compile cache, whatever the environment
    says (JAX_COMPILATION_CACHE_DIR); each ``--one`` subprocess calls this before it measures."""
    from metapg_jax.host import compile_cache

    compile_cache.enable(None)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.bench", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--envs", default=None,
                   help="comma-separated tasks (default: pendulum,inverted_double_pendulum; all tasks with --env-speed)")
    p.add_argument("--methods", default="ddpg,meta")
    p.add_argument("--presets", default="paper,modern")
    p.add_argument("--seeds", default="1,8,32")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--target-steps", type=int, default=None,
                   help="env steps per seed per timed call (default: 3000 pendulum, 600 MuJoCo tasks)")
    p.add_argument("--quick", action="store_true", help="pendulum only, seeds 1 and 8")
    p.add_argument("--out", default=os.path.join(BENCH_DIR, "BENCHMARKS.md"))
    p.add_argument("--json", default=None,
                   help=f"raw numbers (default {BENCH_DIR}/benchmarks.json; {BENCH_DIR}/benchmarks_env_speed.json "
                        "with --env-speed)")
    p.add_argument("--env-speed", action="store_true",
                   help="only environment stepping: ours (--num-envs vmapped envs) vs gymnasium's own")
    p.add_argument("--num-envs", type=int, default=8,
                   help="envs stepped at once by --env-speed (default 8; on a GPU try hundreds: per-step latency "
                        "dominates there)")
    p.add_argument("--stock-mjx", action="store_true",
                   help="MuJoCo tasks with MJX's stock line search (early_exit_linesearch=False): the 'before' "
                        "rows of the line-search change, kept next to the default rows (with --env-speed: an "
                        "extra column)")
    p.add_argument("--physics", default="mjx",
                   help="comma-separated engines of the training rows' MuJoCo tasks: mjx (default), mujoco, "
                        "or mjx,mujoco for both side by side (pendulum rows are JAX either way)")
    p.add_argument("--plain-vmap", action="store_true",
                   help="vmap the seeds without naming the axis: every episode-start branch runs at every step "
                        "(the 'before' rows of that change, kept next to the default rows)")
    p.add_argument("--append", action="store_true", help="add rows to an existing --json (e.g. another grid)")
    p.add_argument("--sweep", action="store_true",
                   help="a 32-setting sweep as one program vs 32 separate runs (the first --envs task, default "
                        "pendulum; the first --seeds value per setting, default 1)")
    p.add_argument("--main-job", action="store_true",
                   help="the README's main job as a user runs it (fresh process, no compile cache), cut at "
                        "--main-job-steps: cold compile and env steps/s on the default engine and on MJX")
    p.add_argument("--main-job-steps", type=int, default=60_000, help="env steps per seed of --main-job (default 60000)")
    p.add_argument("--main-job-physics", default="default,mjx",
                   help="comma-separated --physics values of --main-job ('default' passes none; default: default,mjx)")
    p.add_argument("--one", default=None, help=argparse.SUPPRESS)  # internal: measure one spec (JSON)
    args = p.parse_args(argv)
    if args.one:
        _cold_compiles()
        print("BENCH_RESULT " + json.dumps(measure_one(json.loads(args.one))), flush=True)
        return 0
    import envs

    tasks = args.envs.split(",") if args.envs else (list(envs.TASKS) if args.env_speed else
                                                   ["pendulum", "inverted_double_pendulum"])
    unknown = [t for t in tasks if t not in envs.TASKS]
    if unknown:
        print(f"error: unknown task(s) {', '.join(unknown)}; known: {', '.join(envs.TASKS)}", file=sys.stderr)
        return 2
    if args.num_envs <= 0 or args.repeats <= 0:
        print("error: --num-envs and --repeats must be positive", file=sys.stderr)
        return 2
    from experiments.reproduce import parse_list
    from metapg_jax import strategy
    from metapg_jax.config import PRESETS

    try:
        parse_list(args.methods, tuple(sorted(strategy.explorers())), "method")
        parse_list(args.presets, PRESETS, "preset")
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    try:
        physics = parse_list(args.physics, envs.PHYSICS, "physics")
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    seeds = args.seeds.split(",")
    if not all(s.strip().isdigit() and int(s) > 0 for s in seeds):
        print(f"error: --seeds must be comma-separated positive integers, got {args.seeds!r}", file=sys.stderr)
        return 2
    if args.target_steps is not None and args.target_steps <= 0:
        print(f"error: --target-steps must be positive, got {args.target_steps}", file=sys.stderr)
        return 2
    if args.main_job_steps <= 0:
        print(f"error: --main-job-steps must be positive, got {args.main_job_steps}", file=sys.stderr)
        return 2
    try:
        parse_list(args.main_job_physics, ("default", *envs.PHYSICS_CHOICES), "physics")
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    import jax

    from metapg_jax.host import provenance, runfiles

    _cold_compiles()
    json_path = args.json or os.path.join(BENCH_DIR, "benchmarks_env_speed.json" if args.env_speed
                                          else "benchmarks.json")
    meta = {"date": time.strftime("%Y-%m-%d"), "jax": jax.__version__, "backend": jax.default_backend(),
            "machine": f"{platform.machine()}, {os.cpu_count()} cores, {platform.python_version()}",
            "repeats": args.repeats, "json": json_path}
    if args.sweep:
        json_path = args.json or os.path.join(BENCH_DIR, "benchmarks_sweep.json")
        meta["json"] = json_path
        r = measure_sweep(tasks[0] if args.envs else "pendulum", seeds=int(seeds[0]) if args.seeds != "1,8,32" else 1,
                          repeats=args.repeats)
        runfiles.write_json_atomic(json_path, {"meta": meta, "sweep": r})
        write_section(args.out, "sweep", sweep_markdown(r, meta))
        print(sweep_markdown(r, meta).splitlines()[-1], flush=True)
        return 0
    if args.main_job:
        json_path = args.json or os.path.join(BENCH_DIR, "benchmarks_main_job.json")
        meta["json"] = json_path
        meta.pop("repeats")  # one run per engine
        meta.update({k: v for k, v in provenance.record().items() if k in ("commit", "dirty")})
        rows = []
        for ph in args.main_job_physics.split(","):
            print(f"main job, --physics={ph} ...", flush=True)
            rows.append(measure_main_job(ph, args.main_job_steps))
            print(main_job_markdown(rows, meta).splitlines()[-1], flush=True)
            runfiles.write_json_atomic(json_path, {"meta": meta, "rows": rows})
            write_section(args.out, "main-job", main_job_markdown(rows, meta))
        return 0
    if args.env_speed:
        results = []
        for task in tasks:
            results.append(measure_env_speed(task, num_envs=args.num_envs, repeats=args.repeats,
                                             stock_mjx=args.stock_mjx))
            print(env_speed_markdown(results, meta).splitlines()[-1], flush=True)
            runfiles.write_json_atomic(json_path, {"meta": meta, "env_speed": results})
            write_section(args.out, "env-speed", env_speed_markdown(results, meta))
        return 0
    if args.quick:
        tasks, args.seeds = ["pendulum"], "1,8"
    specs = [{"env": e, "method": m, "preset": pr, "seeds": int(s), "repeats": args.repeats,
              "target_steps": args.target_steps or (3000 if e == "pendulum" else 600),
              "stock_mjx": args.stock_mjx and e != "pendulum", "plain_vmap": args.plain_vmap, "physics": ph}
             for e in tasks for ph in (["mjx"] if e == "pendulum" else physics)
             for m in args.methods.split(",") for pr in args.presets.split(",") for s in args.seeds.split(",")]
    rows, failed = [], []
    if args.append and os.path.exists(json_path):
        with open(json_path) as f:
            rows = json.load(f)["rows"]
    for i, spec in enumerate(specs):
        label = f"{spec['env']} {spec['method']} {spec['preset']} x{spec['seeds']}{_variant(spec)}"
        print(f"[{i + 1}/{len(specs)}] {label} ...", flush=True)
        res = subprocess.run([sys.executable, "-m", "experiments.bench", "--one", json.dumps(spec)],
                             capture_output=True, text=True)
        line = [ln for ln in res.stdout.splitlines() if ln.startswith("BENCH_RESULT ")]
        if res.returncode != 0 or not line:
            print(f"  failed: {res.stderr[-2000:]}", file=sys.stderr)
            failed.append(label)
            continue
        r = json.loads(line[0][len("BENCH_RESULT "):])
        key = lambda x: (x["env"], x["method"], x["preset"], x["seeds"], _variant(x), _date(x))
        rows = [x for x in rows if key(x) != key(r)] + [r]  # re-measured on the same date: replaces the old row
        print(f"  compile {r['compile_s']:.1f} s | {r['steps_per_s_total']:,.0f} steps/s total | env alone "
              f"{r['env_alone_steps_per_s']:,.0f} | updates alone {r['updates_alone_per_s']:,.0f}/s | overhead "
              f"{r['overhead_ratio']:.2f} | eval {r['eval_s']:.2f} s | RSS +{r['rss_growth_mib']:,.0f} MiB "
              f"(buffers {r['buffer_mib']:,.0f})", flush=True)
        # rewritten (atomically) after every row: a long benchmark never loses rows
        runfiles.write_json_atomic(json_path, {"meta": meta, "rows": rows})
        write_markdown(rows, args.out, meta)
    scaling = seed_scaling(rows)
    for r in rows:
        if r["seeds"] == 8 and id(r) in scaling:
            print(f"{_row_md(r, None).split(' | ')[0][2:]} {r['method']} {r['preset']}: 8-seed scaling {scaling[id(r)]:.2f}x")
    if len(failed) < len(specs):  # the files are written after each measured row
        print(f"wrote {args.out} and {json_path}")
    if failed:
        print(f"error: {len(failed)} of {len(specs)} measurements failed: {'; '.join(failed)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
