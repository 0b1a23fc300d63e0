"""Where every second goes: whole training vs environment stepping alone vs DDPG updates alone.

    python -m experiments.bench                       # the default grid (tens of minutes on 2 CPU cores)
    python -m experiments.bench --envs pendulum --seeds 1,8 --repeats 5
    python -m experiments.bench --quick               # pendulum only, 1 and 8 seeds
    python -m experiments.bench --envs hopper,halfcheetah --physics mjx,mujoco --presets paper --seeds 8
    python -m experiments.bench --env-speed           # env stepping alone: MJX, the C engine, its limits
    python -m experiments.bench --sweep               # a 32-setting sweep as one program vs 32 separate runs
    python -m experiments.bench --main-job            # the README's main job: cold compile, first 60k steps
    python -m experiments.bench --checkpoint          # a checkpoint's seconds and bytes: main job, 10-seed modern cell
    python -m experiments.bench --checkpoint-sigterm  # the main job sent SIGTERM: --term-grace 0 vs the default
    python -m experiments.bench --threads             # the C engine at 1 thread and at every core: stepping, training

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
import subprocess
import sys
import tempfile
import time

from experiments.benchmarks import checkpoint as checkpoint_cost
from experiments.benchmarks.env_speed import env_speed_markdown, measure_env_speed
from experiments.benchmarks.main_job import main_job_markdown, measure_main_job
from experiments.benchmarks.records import BENCH_DIR, _date, _variant, write_section
from experiments.benchmarks.sweep import measure_sweep, sweep_markdown
from experiments.benchmarks.training import _row_md, measure_one, seed_scaling, write_markdown


def _cold_compiles() -> None:
    """Compile times here are cold compiles: no persistent compile cache, whatever the environment
    says (JAX_COMPILATION_CACHE_DIR); each ``--one`` subprocess calls this before it measures."""
    from metapg_jax.host import compile_cache

    compile_cache.enable(None)


def grid_strategy(name: str) -> dict:
    """A grid method (``experiments.grid.methods.METHODS``) as a measurement's explorer, student and overrides;
    ``label`` (the method column) is the grid method's name. The preset is the measurement's (``--presets``), also
    for a grid method with a preset of its own."""
    from experiments.grid.methods import METHODS, STUDENT_OF

    m = METHODS[name]
    shortcuts = {"noise": "noise.kind", "teacher": "meta.teacher"}
    unknown = [flag for flag, _ in m.flags if flag not in shortcuts]
    if unknown:
        raise ValueError(f"grid method {name!r}: option --{unknown[0]} is not one experiments.bench reads")
    overrides = {shortcuts[flag]: value for flag, value in m.flags}
    overrides.update(item.split("=", 1) for item in m.overrides)
    spec = {"label": name, "student": STUDENT_OF.get(name, "ddpg"), "method": m.explorer, "overrides": overrides}
    return spec


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.bench", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--envs", default=None,
                   help="comma-separated tasks (default: pendulum,inverted_double_pendulum; all tasks with --env-speed)")
    p.add_argument("--methods", default="ddpg,meta")
    p.add_argument("--strategies", default=None,
                   help="comma-separated grid methods instead of --methods (experiments.grid.methods.METHODS, e.g. "
                        "td3-normal,td3-pink,td3-mixed,sac-own,sac-pink): each with its student and options, "
                        "named in the method column; rows go to the 'strategies' section of --out and to "
                        "benchmarks_strategies.json")
    p.add_argument("--presets", default="paper,modern")
    p.add_argument("--seeds", default="1,8,32")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--target-steps", type=int, default=None,
                   help="env steps per seed per timed call (default: 3000 pendulum, 600 MuJoCo tasks)")
    p.add_argument("--quick", action="store_true", help="pendulum only, seeds 1 and 8")
    p.add_argument("--out", default=None, help=f"the tables (default {BENCH_DIR}/BENCHMARKS.md; "
                                               f"{checkpoint_cost.MARKDOWN} with --checkpoint or --checkpoint-sigterm)")
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
    p.add_argument("--physics", default=None,
                   help="comma-separated engines of the training rows' MuJoCo tasks: mjx (default), mujoco, "
                        "or mjx,mujoco for both side by side (pendulum rows are JAX either way); with --env-speed "
                        "the engines stepped (default mjx,mujoco; mujoco alone skips MJX and the JAX tasks)")
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
    p.add_argument("--checkpoint", action="store_true",
                   help="a checkpoint's seconds and bytes (median of --checkpoint-writes) for the main job and a 10-seed "
                        "modern-preset cell (experiments/benchmarks/checkpoint.py), replay buffers empty and full")
    p.add_argument("--checkpoint-writes", type=int, default=3, help="writes per measurement of --checkpoint (default 3)")
    p.add_argument("--checkpoint-sigterm", action="store_true",
                   help="the main job sent SIGTERM in its 4th chunk, before its first checkpoint (a second into the "
                        "chunk with --term-grace 0 and the default, and 10 s before its end with the default): its "
                        "exit, its checkpoint and the training it lost")
    p.add_argument("--threads", action="store_true",
                   help="MuJoCo's C engine at 1 thread and at every core: env stepping alone (--envs, default "
                        "hopper,halfcheetah,inverted_double_pendulum,gym:Walker2d-v5; --threads-envs counts) and "
                        "10-seed TD3 training (--threads-training tasks); results/benchmarks/threads.md")
    p.add_argument("--threads-envs", default="8,10,32", help="env counts of --threads (default 8,10,32)")
    p.add_argument("--threads-training", default="hopper,halfcheetah,gym:Walker2d-v5",
                   help="tasks of --threads' training rows ('' for none; default hopper,halfcheetah,gym:Walker2d-v5)")
    p.add_argument("--note", default="", help="a line on the machine's conditions, written with --checkpoint's tables")
    p.add_argument("--one", default=None, help=argparse.SUPPRESS)  # internal: measure one spec (JSON)
    args = p.parse_args(argv)
    if args.one:
        _cold_compiles()
        print("BENCH_RESULT " + json.dumps(measure_one(json.loads(args.one))), flush=True)
        return 0
    import envs

    if args.threads:
        return _threads(args)
    tasks = args.envs.split(",") if args.envs else (list(envs.TASKS) if args.env_speed else
                                                   ["pendulum", "inverted_double_pendulum"])
    try:
        for t in tasks:
            envs.get_spec(t)  # a built-in task, or gym:/dmc: (one-line error)
            if envs.is_gym_task(t) and args.env_speed:
                raise ValueError(f"--env-speed measures the built-in and dmc: tasks; {t} has no model of ours")
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if args.num_envs <= 0 or args.repeats <= 0:
        print("error: --num-envs and --repeats must be positive", file=sys.stderr)
        return 2
    from experiments.reproduce import parse_list
    from metapg_jax import strategy
    from metapg_jax.config import PRESETS

    from experiments.grid.methods import METHODS

    try:
        parse_list(args.methods, tuple(sorted(strategy.explorers())), "method")
        if args.strategies:
            parse_list(args.strategies, tuple(METHODS), "grid method")
        parse_list(args.presets, PRESETS, "preset")
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    try:
        physics = parse_list(args.physics or ("mjx,mujoco" if args.env_speed else "mjx"), envs.PHYSICS, "physics")
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if args.env_speed and "mjx" not in physics and not any(envs.has_mujoco(t) for t in tasks):
        print("error: --physics=mujoco steps only MuJoCo tasks; --envs names none", file=sys.stderr)
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
    if args.checkpoint_writes <= 0:
        print(f"error: --checkpoint-writes must be positive, got {args.checkpoint_writes}", file=sys.stderr)
        return 2
    try:
        parse_list(args.main_job_physics, ("default", *envs.PHYSICS_CHOICES), "physics")
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    import jax

    from metapg_jax.host import provenance, runfiles

    _cold_compiles()
    if args.strategies:  # a section and raw file of their own: the training rows of the default grid stay
        args.json = args.json or os.path.join(BENCH_DIR, "benchmarks_strategies.json")
    json_path = args.json or os.path.join(BENCH_DIR, "benchmarks_env_speed.json" if args.env_speed
                                          else "benchmarks.json")
    meta = {"date": time.strftime("%Y-%m-%d"), "jax": jax.__version__, "backend": jax.default_backend(),
            "machine": f"{platform.machine()}, {os.cpu_count()} cores, {platform.python_version()}",
            "repeats": args.repeats, "json": json_path}
    if args.checkpoint or args.checkpoint_sigterm:
        return _checkpoint(args, meta)
    args.out = args.out or os.path.join(BENCH_DIR, "BENCHMARKS.md")
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
        meta.update({k: v for k, v in provenance.record().items() if k in ("commit", "dirty")})
        results = []
        for task in tasks if "mjx" in physics else [t for t in tasks if envs.has_mujoco(t)]:
            results.append(measure_env_speed(task, num_envs=args.num_envs, repeats=args.repeats,
                                             stock_mjx=args.stock_mjx, engines=physics))
            print(env_speed_markdown(results, meta).splitlines()[-1], flush=True)
            runfiles.write_json_atomic(json_path, {"meta": meta, "env_speed": results})
            write_section(args.out, "env-speed", env_speed_markdown(results, meta))
        return 0
    if args.quick:
        tasks, args.seeds = ["pendulum"], "1,8"
    strategies = ([grid_strategy(name) for name in args.strategies.split(",")] if args.strategies else
                  [{"method": m} for m in args.methods.split(",")])
    specs = [{"env": e, **m, "preset": pr, "seeds": int(s), "repeats": args.repeats,
              "target_steps": args.target_steps or (600 if envs.has_mujoco(e) else 3000),
              "stock_mjx": args.stock_mjx and envs.has_mujoco(e), "plain_vmap": args.plain_vmap, "physics": ph}
             for e in tasks for ph in (physics if envs.has_mujoco(e) else ["mjx"])
             for m in strategies for pr in args.presets.split(",") for s in args.seeds.split(",")]
    rows, failed = [], []
    if args.append and os.path.exists(json_path):
        with open(json_path) as f:
            rows = json.load(f)["rows"]
    for i, spec in enumerate(specs):
        label = f"{spec['env']} {spec.get('label', spec['method'])} {spec['preset']} x{spec['seeds']}{_variant(spec)}"
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
        write_markdown(rows, args.out, meta, section="strategies" if args.strategies else "training")
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


def _checkpoint(args: argparse.Namespace, meta: dict) -> int:
    """``--checkpoint`` and ``--checkpoint-sigterm``: their measurements, JSON and sections of their markdown."""
    from metapg_jax.host import provenance, runfiles
    from metapg_jax.host.runner import TERM_GRACE

    out = args.out or checkpoint_cost.MARKDOWN
    if not os.path.exists(out):
        with open(out, "w") as f:
            f.write(checkpoint_cost.TITLE)
    meta.pop("repeats")
    meta.update({k: v for k, v in provenance.record().items() if k in ("commit", "dirty")})
    meta["conditions"] = f"load average {os.getloadavg()[0]:.1f} when it started" + (
        f"; {args.note}" if args.note else "")
    if args.checkpoint:
        meta["json"] = args.json or os.path.splitext(out)[0] + ".json"
        rows = []
        for label, argv in checkpoint_cost.CASES.items():
            print(f"checkpoint of the {label} ...", flush=True)
            rows.append(checkpoint_cost.measure_checkpoint(label, argv, args.checkpoint_writes))
            print(f"  empty {rows[-1]['empty']}, full {rows[-1]['full']}", flush=True)
            runfiles.write_json_atomic(meta["json"], {"meta": meta, "rows": rows})
        write_section(out, "checkpoint-cost", checkpoint_cost.checkpoint_markdown(rows, meta, TERM_GRACE))
    if args.checkpoint_sigterm:
        meta["json"] = args.json or os.path.splitext(out)[0] + "-sigterm.json"
        rows, steps = [], 150_000
        with tempfile.TemporaryDirectory(prefix="metapg-sigterm-cache-") as cache:
            # A second into the chunk (the most it can have left), and with about 10 s of it to go.
            for grace, when in ((0.0, {"into": 1.0}), (TERM_GRACE, {"into": 1.0}), (TERM_GRACE, {"left": 10.0})):
                print(f"main job, SIGTERM with --term-grace={grace:g} ({when}) ...", flush=True)
                rows.append(checkpoint_cost.measure_sigterm(grace, steps, after_chunks=3, cache=cache, **when))
                print(f"  {rows[-1]}", flush=True)
                runfiles.write_json_atomic(meta["json"], {"meta": meta, "rows": rows})
        write_section(out, "checkpoint-sigterm", checkpoint_cost.sigterm_markdown(rows, meta, steps))
    print(f"wrote {out}", flush=True)
    return 0


def _threads(args: argparse.Namespace) -> int:
    """``--threads``: its checks, measurements, JSON and markdown (``experiments/benchmarks/threads.py``)."""
    import envs
    import jax

    from envs.host_call import default_threads
    from experiments.benchmarks import threads as bench_threads
    from metapg_jax.host import provenance, runfiles

    tasks = (args.envs or "hopper,halfcheetah,inverted_double_pendulum,gym:Walker2d-v5").split(",")
    training = [t for t in args.threads_training.split(",") if t]
    try:
        for t in tasks + training:
            if not envs.has_mujoco(t):
                raise ValueError(f"--threads measures MuJoCo's C engine; {t} is a JAX task")
        counts = [int(x) for x in args.threads_envs.split(",")]
        if min(counts) <= 0 or args.repeats <= 0:
            raise ValueError("--threads-envs and --repeats must be positive")
    except ValueError as err:
        print(f"error: {str(err).splitlines()[0]}", file=sys.stderr)
        return 2
    n = default_threads()
    if n < 2:
        print(f"error: --threads compares 1 thread with several, and this process may use {n} CPU", file=sys.stderr)
        return 2
    _cold_compiles()
    out = args.out or os.path.join(BENCH_DIR, "threads.md")
    meta = {"date": time.strftime("%Y-%m-%d"), "jax": jax.__version__, "threads": n, "repeats": args.repeats,
            "machine": f"{platform.machine()}, {os.cpu_count()} cores, {platform.python_version()}",
            "json": args.json or os.path.splitext(out)[0] + ".json",
            "conditions": f"load average {os.getloadavg()[0]:.1f} when it started" + (f"; {args.note}" if args.note else ""),
            **{k: v for k, v in provenance.record().items() if k in ("commit", "dirty")}}
    if not os.path.exists(out):
        with open(out, "w") as f:
            f.write("# MuJoCo's C engine on one thread and on several\n")
    stepping, trained = [], []

    def save():
        runfiles.write_json_atomic(meta["json"], {"meta": meta, "stepping": stepping, "training": trained})
        write_section(out, "threads", bench_threads.threads_markdown(stepping, trained, meta))

    for task in tasks:
        for num in counts:
            print(f"stepping {task}, {num} envs ...", flush=True)
            stepping.append(bench_threads.measure_stepping(task, num, n, repeats=args.repeats))
            save()
            print(bench_threads.threads_markdown(stepping, [], meta).splitlines()[-1], flush=True)
    for task in training:
        for k in (1, n):
            print(f"training {task}, {k} thread(s) ...", flush=True)
            trained.append(bench_threads.measure_training(task, k, repeats=args.repeats))
            save()
            print(f"  {trained[-1]['steps_per_s']:,.0f} env steps/s", flush=True)
    print(f"wrote {out}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
