"""Env stepping alone (``python -m experiments.bench --env-speed``): our tasks on MJX and on MuJoCo's C
engine inside the program, the C engine's loops outside JAX, gymnasium's own env; and their table."""

from __future__ import annotations

import os
import statistics
import time

from experiments.benchmarks.timing import _timed


MECHANISMS = ("raw", "batch", "rollout", "pool")


def _c_loops(task: str, num_envs: int, steps: int, threads: int, repeats: int, mechanisms=MECHANISMS) -> dict:
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

    ``mechanisms``: which of the four to time (``experiments.benchmarks.threads`` times the first two). A ``gym:``
    task: its gymnasium env's model and frame skip.
    """
    from concurrent.futures import ThreadPoolExecutor

    import mujoco
    import numpy as np
    from mujoco import batch as mj_batch
    from mujoco import rollout as mj_rollout

    import envs

    raw_env = envs.make_raw(task, physics="mujoco", physics_threads=1)
    model, fs = raw_env.mj_model, int(raw_env.frame_skip)
    derived = getattr(getattr(raw_env, "task", None), "derived_fields", ())  # what the task math reads
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
    for name in derived:
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

    runs = {"raw": ("raw_loop_steps_per_s", raw), "batch": ("batch_steps_per_s", batch),
            "rollout": ("rollout_steps_per_s", rollout), "pool": ("pool_steps_per_s", pooled)}
    return {**{runs[m][0]: median_rate(runs[m][1]) for m in mechanisms}, "c_threads": threads}


def time_stepping(task: str, num_envs: int, steps: int, repeats: int, trajectory: bool = False, **overrides):
    """``envs.make(task, **overrides)`` stepped alone: a jitted scan of ``steps`` uniform-random steps of
    ``num_envs`` vmapped envs with the training wrappers (auto-reset included). Returns (steps/s, median of
    ``repeats``; every repeat's seconds; compile seconds; with ``trajectory``, the (obs, reward) of one more call,
    else None)."""
    import jax
    import jax.numpy as jnp

    import envs

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
    traj = jax.device_get(fn(state, jax.random.PRNGKey(1))[1]) if trajectory else None
    return num_envs * steps / seconds, times, compile_s, traj


def measure_env_speed(task: str, num_envs: int = 8, steps: int = 1000, repeats: int = 3,
                      stock_mjx: bool = False, engines=("mjx", "mujoco")) -> dict:
    """Env stepping alone, ``num_envs`` envs: our task through the compiled program (a jitted scan,
    vmapped, with the training wrappers, auto-reset included) on each engine: MJX and MuJoCo's C
    engine through the host callback (``physics='mujoco'``); for the MuJoCo tasks the C engine's
    loops outside JAX (``_c_loops``); and gymnasium's own env stepped one at a time in a Python loop.

    With ``stock_mjx``, MJX is timed a second time with its stock line search
    (``early_exit_linesearch=False``) and the two trajectories are checked to be identical
    (see envs/mujoco_base.py, "Speed"). ``engines`` without "mjx": the C engine's columns alone (a MuJoCo task)."""
    import numpy as np

    import envs
    from envs.host_call import default_threads

    def time_ours(**overrides):
        return time_stepping(task, num_envs, steps, repeats, trajectory=True, **overrides)

    out = {"task": task, "num_envs": num_envs, "steps": steps}
    if "mjx" in engines or not envs.has_mujoco(task):
        ours, ours_times, out["compile_s"], traj = time_ours()
        out.update(ours_steps_per_s=ours, ours_times=ours_times)
    if envs.has_mujoco(task) and "mujoco" in engines:
        threads = default_threads()
        c, c_times, c_compile_s, _ = time_ours(physics="mujoco")
        out.update(c_steps_per_s=c, c_times=c_times, c_compile_s=c_compile_s,
                   **_c_loops(task, num_envs, steps, threads, repeats))
        if "ours_steps_per_s" in out:
            out["c_over_mjx"] = c / out["ours_steps_per_s"]
        out["c_over_raw_loop"] = c / out["raw_loop_steps_per_s"]
        out["c_over_batch"] = c / out["batch_steps_per_s"]
        # What one step of the batch costs in the program on top of the same physics outside JAX: the
        # host call, the task math in numpy, the resets, the wrappers' and the program's own work.
        out["c_overhead_us_per_step"] = 1e6 * num_envs * (1 / c - 1 / out["batch_steps_per_s"])
        if stock_mjx and "mjx" in engines:
            stock, stock_times, stock_compile_s, stock_traj = time_ours(early_exit_linesearch=False)
            out.update(stock_steps_per_s=stock, stock_times=stock_times, stock_compile_s=stock_compile_s,
                       early_exit_speedup=ours / stock,
                       identical_to_stock=all(np.array_equal(a, b) for a, b in zip(traj, stock_traj)))

    out["gymnasium_steps_per_s"] = _reference_speed(task)
    return out


def _reference_speed(task: str, n: int = 3000) -> float:
    """The task's reference implementation stepped one env at a time in a Python loop, random actions, resets
    at its episode ends: gymnasium's env, or dm_control's suite for a ``dmc:`` task. Steps/s."""
    import numpy as np

    import envs

    rng = np.random.default_rng(0)
    if envs.is_dmc_task(task):
        os.environ.setdefault("MUJOCO_GL", "disable")
        from dm_control import suite

        from envs.dmc_names import parse_name

        env = suite.load(*parse_name(task), task_kwargs={"random": 0})
        spec = env.action_spec()
        env.reset()
        t = time.perf_counter()
        for _ in range(n):
            if env.step(rng.uniform(spec.minimum, spec.maximum)).last():
                env.reset()
        return n / (time.perf_counter() - t)
    import gymnasium

    genv = gymnasium.make(envs.get_spec(task).gym_id)
    genv.reset(seed=0)
    low, high = genv.action_space.low, genv.action_space.high
    t = time.perf_counter()
    for _ in range(n):
        _, _, term, trunc, _ = genv.step(rng.uniform(low, high).astype(np.float32))
        if term or trunc:
            genv.reset()
    return n / (time.perf_counter() - t)


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
    commit = f" at {meta['commit'][:7]}{' (with changes)' if meta.get('dirty') else ''}" if "commit" in meta else ""
    lines = [
        f"`python -m experiments.bench --env-speed` on {meta['date']}{commit} ({meta['machine']}; jax {meta['jax']}, "
        f"backend {meta['backend']}; medians of {meta['repeats']} timed repeats; raw numbers: "
        f"`{os.path.basename(meta['json'])}`), all in one process per run: our tasks, {n} envs vmapped in a "
        f"jitted scan of {results[0]['steps']:,} uniform-random steps with the training wrappers (auto-reset "
        "included), on MJX and on MuJoCo's C engine through the host callback (`--physics=mujoco`"
        + (f", {threads} threads" if threads else "") + "). Then the C engine outside JAX on the same model, "
        f"{n} simulations, random controls, no resets: a plain loop of `mj_step` over one `MjData` each "
        "(one thread: the 'raw loop'), `mujoco.batch.Batch` (what the callback uses), `mujoco.rollout` and "
        "our own `MjData` loop on a Python thread pool (both with the same threads); the program's cost per step "
        f"is the C engine's time per step of the {n} envs in the program minus the batch's outside it (the host "
        "call, the task math in numpy, resets, wrappers). Last, the reference implementation (gymnasium's own "
        "env; dm_control's suite for a `dmc:` task) stepped one env at a time in a Python loop. Targets: C engine >= "
        f"{ENV_SPEED_TARGETS['c_over_raw_loop']}x the raw loop on every task, and >= 5x MJX on Hopper and "
        "HalfCheetah, >= 1.5x on IDP.", "",
        "| task | MJX, steps/s | C engine in the program, steps/s | C / MJX | raw C loop | C / raw loop | "
        "batch outside JAX | program's cost per step, us | rollout module | own thread pool | targets met | "
        "reference, 1 env | compile s, MJX / C |",
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

