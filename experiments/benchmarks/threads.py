"""MuJoCo's C engine on one thread and on several (``python -m experiments.bench --threads``): env stepping
alone inside the program against MuJoCo's own loops outside JAX, and whole training, at each thread count;
and their tables.

The thread count changes no number (each env steps on its own; tests/test_physics.py and
tests/test_gym_tasks.py check it bit for bit), only the speed, so the rows here are the whole case for
``--physics-threads`` and for its default.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

from experiments.benchmarks.env_speed import _c_loops, time_stepping

# The training rows: 10-seed TD3 with Gaussian noise (what the benchmark grids run) under the paper preset.
TRAINING = {"method": "ddpg", "student": "td3", "overrides": {"noise.kind": "normal"}, "preset": "paper",
            "seeds": 10, "target_steps": 600}


def _outside_jax(task: str, num_envs: int, steps: int, threads: int, repeats: int) -> dict:
    """The task's model stepped outside JAX (``env_speed._c_loops``): a plain ``mj_step`` loop on one thread, and
    ``mujoco.batch.Batch`` (what the callback uses) on 1 and ``threads`` threads. Steps/s, medians of ``repeats``."""
    one = _c_loops(task, num_envs, steps, 1, repeats, mechanisms=("raw", "batch"))
    many = _c_loops(task, num_envs, steps, threads, repeats, mechanisms=("batch",))
    return {"loop_1": one["raw_loop_steps_per_s"], "batch_1": one["batch_steps_per_s"],
            f"batch_{threads}": many["batch_steps_per_s"]}


def _in_program(task: str, num_envs: int, steps: int, threads: int, repeats: int) -> float:
    """The task on the C engine inside the program at ``threads`` threads (``env_speed.time_stepping``): steps/s,
    the median of ``repeats``."""
    return time_stepping(task, num_envs, steps, repeats, physics="mujoco", physics_threads=threads)[0]


def measure_stepping(task: str, num_envs: int, threads: int, steps: int = 500, repeats: int = 3) -> dict:
    """One row of env stepping alone: in the program at 1 and ``threads`` threads, and outside JAX."""
    one = _in_program(task, num_envs, steps, 1, repeats)
    many = _in_program(task, num_envs, steps, threads, repeats)
    out = {"task": task, "num_envs": num_envs, "threads": threads, "steps": steps,
           "program_1": one, f"program_{threads}": many, **_outside_jax(task, num_envs, steps, threads, repeats)}
    out["threads_gain_in_program"] = many / one
    out["threads_gain_outside"] = out[f"batch_{threads}"] / out["batch_1"]
    out["program_over_loop"] = many / out["loop_1"]
    out["program_over_threaded_batch"] = many / out[f"batch_{threads}"]
    return out


def measure_training(task: str, threads: int, repeats: int = 3) -> dict:
    """Whole training (``TRAINING``) on the C engine at ``threads`` threads: ``experiments.bench --one`` in a
    subprocess of its own with ``$METAPG_PHYSICS_THREADS`` set."""
    from envs.host_call import THREADS_VARIABLE

    spec = {"env": task, **TRAINING, "repeats": repeats, "physics": "mujoco"}
    env = {**os.environ, THREADS_VARIABLE: str(threads)}
    res = subprocess.run([sys.executable, "-m", "experiments.bench", "--one", json.dumps(spec)], capture_output=True,
                         text=True, env=env)
    line = [ln for ln in res.stdout.splitlines() if ln.startswith("BENCH_RESULT ")]
    if res.returncode != 0 or not line:
        raise RuntimeError(f"{task} at {threads} thread(s) failed: {res.stderr[-2000:]}")
    r = json.loads(line[0][len("BENCH_RESULT "):])
    return {"task": task, "threads": threads, "steps_per_s": r["steps_per_s_total"],
            "env_alone_steps_per_s": r["env_alone_steps_per_s"], "compile_s": r["compile_s"]}


def threads_markdown(stepping: list[dict], training: list[dict], meta: dict) -> str:
    n = meta["threads"]
    commit = f" at {meta['commit'][:7]}{' (with changes)' if meta.get('dirty') else ''}" if "commit" in meta else ""
    lines = [
        f"`python -m experiments.bench --threads` on {meta['date']}{commit} ({meta['machine']}; jax {meta['jax']}; "
        f"medians of {meta['repeats']} timed repeats; {meta['conditions']}; raw numbers: "
        f"`{os.path.basename(meta['json'])}`), one process. Env stepping alone: each task's envs vmapped in a "
        f"jitted scan of uniform-random steps with the training wrappers (auto-reset included) on MuJoCo's C "
        f"engine inside the program, at 1 thread and at {n}; then outside JAX on the same model: a plain "
        f"`mj_step` loop over one `MjData` per env (one thread) and `mujoco.batch.Batch` at 1 and {n} threads "
        f"(random controls, no resets). Target: the program at {n} threads within 1.2x of the threaded batch "
        f"outside JAX.", "",
        f"| task | envs | program, 1 thread | program, {n} threads | gain in the program | `mj_step` loop, 1 thread "
        f"| batch, 1 thread | batch, {n} threads | gain outside JAX | program / loop | program / threaded batch |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in stepping:
        lines.append(
            f"| {r['task']} | {r['num_envs']} | {r['program_1']:,.0f} | {r[f'program_{n}']:,.0f} | "
            f"{r['threads_gain_in_program']:.2f}x | {r['loop_1']:,.0f} | {r['batch_1']:,.0f} | {r[f'batch_{n}']:,.0f} | "
            f"{r['threads_gain_outside']:.2f}x | {r['program_over_loop']:.2f}x | "
            f"{1 / r['program_over_threaded_batch']:.2f}x slower |")
    if training:
        lines += ["", f"Training: {TRAINING['seeds']}-seed TD3 with Gaussian noise, {TRAINING['preset']} preset, on "
                      f"the C engine (`experiments.bench --one`, a process per row, cold compile), whole cycles, env "
                      f"steps/s of all seeds together.", "",
                  f"| task | 1 thread | {n} threads | gain |", "|---|---|---|---|"]
        by = {(r["task"], r["threads"]): r for r in training}
        for task in dict.fromkeys(r["task"] for r in training):
            a, b = by.get((task, 1)), by.get((task, n))
            if a and b:
                lines.append(f"| {task} | {a['steps_per_s']:,.0f} | {b['steps_per_s']:,.0f} | "
                             f"{b['steps_per_s'] / a['steps_per_s']:.2f}x |")
    return "\n".join(lines)
