"""Run (or resume) the paper's grid of task x method x seeds, then rebuild every artefact.

    python -m experiments.reproduce                                   # the whole grid, paper preset, 8 seeds
    python -m experiments.reproduce --tasks pendulum,reacher --methods meta-independent,ddpg-paramnoise
    python -m experiments.reproduce --preset modern                  # results/modern/
    python -m experiments.reproduce --preset tuned --physics mujoco --results-dir results   # results/tuned/
    python -m experiments.reproduce --artefacts-only --embedding pca  # no training, rebuild from what is stored

Each grid cell is one ``experiments.run.main`` call writing
``<runs-dir>/<preset>/<task>/<method>``, run one after another in the paper's
task order (InvertedDoublePendulum first). Run folders are not committed
(checkpoints are large); every finished cell's results (config, metrics,
summary, provenance, a thinned state-visitation sample) are copied into the
committed archive ``<results-dir>/cells/<task>/<method>`` when the artefacts
are rebuilt and as soon as a cell finishes. A cell whose ``summary.json``
exists is skipped (so is one with no run folder whose results are archived);
one with a checkpoint but no summary is resumed (with the
same explicit options, so ``--resume`` checks they match); one with neither
(killed before its first checkpoint) is started again. A finished cell whose
budget is below the requested one (e.g. a reduced-budget cell, when the grid is
run again at the paper's budget) is *extended* from its final checkpoint
(``experiments.run --resume <cell> --steps=<budget>``: the same numbers as a run
started at that budget); until the extension finishes, the archive keeps the
shorter cell. Next to each cell's
run outputs, ``reproduce.json`` records the commit, the machine, the command
and the accumulated wall time of this script's calls for that cell.

``--launcher ray`` runs every cell that has work left as a Ray task (``run_grid_ray``; a local Ray
instance unless ``--ray-address`` names a cluster): the same planning and archiving in the worker, and
a cell whose worker died is retried by Ray and resumes from its checkpoint (docs/reproducing.md).
``--student td3`` runs the TD3 grid (``experiments.grid.GRIDS``) into ``runs/reproduce-td3`` and
``results/td3``.

Then ``experiments.artefacts.build_all`` rebuilds Table 2, the learning
curves, steps-to-threshold, the teacher-design and state-visitation figures,
``README.md`` and ``manifest.json`` under ``--results-dir`` (``<results-dir>/
<preset>`` for a preset other than ``paper``) from whatever is stored.

Exit status: 0 every requested cell finished; 2 bad input; 3 some cell stopped
on non-finite parameters (the others still ran); 130 interrupted (143 by SIGTERM) (artefacts
are still rebuilt from what is stored; run the same command again to resume).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

from experiments.artefacts import add_figure_options, build_all
from experiments.cells import archive_cell, archive_dir_for, read_json, results_dir_for
from experiments.grid import BASELINES, GRIDS, METHODS, TASKS, baseline_for, methods_for

# Where --physics=mujoco keeps its grid by default, apart from the MJX grid's runs/reproduce and results.
MUJOCO_RUNS, MUJOCO_RESULTS = "runs/reproduce-mujoco", "results/mujoco"
# Where a student other than DDPG keeps its grid by default (whatever the physics): runs/reproduce-<student>
# and results/<student>.
RUN_ORDER = ("inverted_double_pendulum", "pendulum", "inverted_pendulum", "reacher", "hopper", "halfcheetah")
DEFAULT_SEEDS = 8


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m experiments.reproduce",
        description="Run or resume the paper's task x method grid (skipping finished cells), then rebuild "
                    "Table 2 and the figures from the stored results.")
    p.add_argument("--tasks", default=",".join(RUN_ORDER),
                   help=f"comma-separated tasks, run in this order (default: {','.join(RUN_ORDER)})")
    p.add_argument("--methods", default=None,
                   help="comma-separated methods of the student's grid (default: all of them): "
                        + "; ".join(f"{s}: {', '.join(m)}" for s, m in GRIDS.items()))
    p.add_argument("--student", default="ddpg", choices=tuple(GRIDS),
                   help="the learner of every cell: ddpg (default) or td3 (its grid: TD3 with Gaussian noise 0.1 vs "
                        "Meta on TD3; cells go to runs/reproduce-td3 and results/td3 unless --runs-dir/--results-dir "
                        "are given)")
    p.add_argument("--seeds", type=int, default=DEFAULT_SEEDS, help=f"seeds per cell (default {DEFAULT_SEEDS})")
    p.add_argument("--seed", type=int, default=0, help="base PRNG seed of every cell (default 0)")
    p.add_argument("--steps", type=int, default=None,
                   help="env steps per seed for every cell (default: each task's paper budget)")
    p.add_argument("--preset", default="paper", choices=tuple(BASELINES),
                   help="'paper' (default; results in --results-dir), 'modern' or 'tuned' (results in "
                        "<results-dir>/<preset>)")
    p.add_argument("--source", default="gymnasium", help="MuJoCo models: gymnasium (default) or brax")
    p.add_argument("--physics", default="mjx", choices=("mjx", "mujoco"),
                   help="engine of the MuJoCo tasks: mjx (default) or mujoco (MuJoCo's C engine; its cells go to "
                        f"{MUJOCO_RUNS} and {MUJOCO_RESULTS} unless --runs-dir/--results-dir are given; "
                        "pendulum cells run on their JAX physics either way)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="GROUP.FIELD=VALUE",
                   help="config override passed to every cell's experiments.run (e.g. tiny test settings)")
    p.add_argument("--runs-dir", default=None, help="grid root (default runs/reproduce)")
    p.add_argument("--results-dir", default=None, help="artefact folder (default results)")
    p.add_argument("--artefacts-only", action="store_true", help="train nothing; rebuild the artefacts only")
    add_figure_options(p)
    p.add_argument("--no-plot", action="store_true", help="skip each run's own PNGs (the artefacts are still drawn)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--tensorboard", action="store_true",
                   help="each cell also writes TensorBoard scalars to <cell>/tensorboard/seed_<i>/ (experiments.run "
                        "--tensorboard; needs the tensorboard extra, tensorboardX)")
    p.add_argument("--checkpoint-every", type=int, default=0, metavar="CHUNKS",
                   help="each cell checkpoints every CHUNKS chunks (experiments.run --checkpoint-every; default 0: "
                        "every --checkpoint-minutes)")
    p.add_argument("--checkpoint-minutes", type=float, default=5.0,
                   help="each cell's minimum minutes between checkpoints (experiments.run; default 5)")
    p.add_argument("--dry-run", action="store_true", help="print what would be run, skipped or resumed; do nothing")
    p.add_argument("--launcher", default="local", choices=("local", "ray"),
                   help="local (default): the cells one after another in this process; ray: each cell a Ray task "
                        "(the ray extra), on a local Ray instance started here, or on --ray-address")
    p.add_argument("--ray-address", default=None, metavar="HOST:PORT|auto",
                   help="an existing Ray cluster (default: start a local instance); its nodes need this package "
                        "installed and --runs-dir/--results-dir on a shared file system")
    p.add_argument("--ray-cpus-per-cell", type=float, default=1.0, help="CPUs each cell's task asks Ray for (default 1)")
    p.add_argument("--ray-gpus-per-cell", type=float, default=0.0, help="GPUs each cell's task asks Ray for (default 0)")
    p.add_argument("--ray-retries", type=int, default=3,
                   help="times Ray restarts a cell whose worker died (it resumes from its last checkpoint; default 3)")
    return p


def parse_list(text: str, valid, what: str) -> list[str]:
    items = [t.strip() for t in text.split(",") if t.strip()]
    bad = [t for t in items if t not in valid]
    if bad or not items:
        raise ValueError(f"unknown {what} {', '.join(map(repr, bad)) or '(none given)'}; valid: {', '.join(valid)}")
    if len(set(items)) != len(items):
        raise ValueError(f"--{what}s lists a {what} twice")
    return items


def cell_dir(runs_dir: str, preset: str, task: str, method: str) -> str:
    return os.path.join(runs_dir, preset, task, method)


def cell_state(path: str) -> str:
    """'done' (summary.json), 'resume' (a checkpoint, no summary), 'restart' (a folder without a checkpoint)
    or 'new'."""
    if os.path.exists(os.path.join(path, "summary.json")):
        return "done"
    from metapg_jax.host.checkpoint import saved_steps

    if saved_steps(os.path.join(path, "checkpoints")):
        return "resume"
    if os.path.isdir(path) and os.listdir(path):
        return "restart"
    return "new"


def finished_at_budget(args: argparse.Namespace, task: str, method: str) -> bool:
    """Whether the cell's run folder or its archived copy finished at (at least) the requested budget."""
    wanted = wanted_budget(args, task)
    for path in (cell_dir(args.runs_dir, args.preset, task, method),
                 os.path.join(archive_dir_for(args.results_dir, args.preset), task, method)):
        summary = read_json(os.path.join(path, "summary.json"))
        if summary and summary["env_steps"] >= wanted:
            return True
    return False


def wanted_budget(args: argparse.Namespace, task: str) -> int:
    """The requested env steps per seed: ``--steps``, else the paper's budget for the task (as make_config)."""
    from envs import default_budget

    return default_budget(task) if args.steps is None else args.steps


def cell_argv(args: argparse.Namespace, task: str, method: str, out: str, state: str,
              options: list[str] | None = None) -> list[str]:
    """The explicit ``experiments.run`` options of a cell (the same for a fresh start and a resume; an
    extension names the new budget). ``options`` replaces the grid method's ``METHODS[method]`` (a grid of
    other variants, e.g. ``experiments.screen``'s)."""
    options = METHODS[method] if options is None else options
    argv = [f"--env={task}", *options, f"--preset={args.preset}", f"--seeds={args.seeds}",
            f"--seed={args.seed}", f"--source={args.source}"]
    if task != "pendulum":  # named always: experiments.run's own default, 'auto', depends on the backend
        argv.append(f"--physics={args.physics}")
    if args.student != "ddpg":
        argv.append(f"--student={args.student}")
    if args.steps is not None or state == "extend":
        argv.append(f"--steps={wanted_budget(args, task)}")
    for item in args.overrides:
        argv += ["--set", item]
    if args.no_plot:
        argv.append("--no-plot")
    if args.quiet:
        argv.append("--quiet")
    if args.tensorboard:
        argv.append("--tensorboard")
    if args.checkpoint_every:
        argv.append(f"--checkpoint-every={args.checkpoint_every}")
    if args.checkpoint_minutes != 5.0:
        argv.append(f"--checkpoint-minutes={args.checkpoint_minutes:g}")
    if state in ("resume", "extend"):
        argv += ["--resume", out]
    else:
        argv += ["--out", out] + (["--overwrite"] if state == "restart" else [])
    return argv


def requested_config(args: argparse.Namespace, task: str, method: str, options: list[str] | None = None):
    """The config a fresh run of this cell at the requested budget gets (validated)."""
    from experiments import run as run_lib

    parsed = run_lib.build_parser().parse_args(cell_argv(args, task, method, os.devnull, "new", options))
    return run_lib.config_from_run_args(run_lib.run_args(parsed))


def _write_cell_record(out: str, argv: list[str], status: int, seconds: float, started: dict,
                       diff: str = "") -> None:
    """``reproduce.json`` in the cell: commit, machine, command, status and accumulated wall time; a call
    started from a tree with uncommitted code changes stores them (``diff``, taken when it started) beside the
    record as ``uncommitted-<call>.diff``, named in its call entry, and archived with the cell.

    ``started`` is ``provenance.record()`` taken when the call began (the code that ran, even if
    the checkout changed while it ran); every call (a resume is one) keeps its own commit, and the
    top-level ``commit`` is the one the cell was started at (its config.json's, also when the first call was
    killed before it could write this record; ``wall_seconds`` then counts the recorded calls only; the
    results manifest's ``train_seconds_all_calls`` adds up every call's training from the metrics rows)."""
    from metapg_jax.host import runfiles

    path = os.path.join(out, "reproduce.json")
    calls = read_json(path).get("calls", [])
    call = {"argv": argv, "status": status, "wall_seconds": round(seconds, 2), "commit": started["commit"],
            "dirty": started["dirty"], "ended": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    if started["dirty"]:
        call["diff"] = f"uncommitted-{len(calls) + 1}.diff"
        with open(os.path.join(out, call["diff"]), "w") as f:
            f.write(diff if diff.endswith("\n") or not diff else diff + "\n")
    calls = calls + [call]
    # A call killed before it wrote its record (session end, SIGKILL) still started the cell: config.json's
    # commit wins; the first recorded call's is the fallback for a cell without one.
    cfg = read_json(os.path.join(out, "config.json"))
    first = ({"commit": cfg["commit"], "dirty": cfg.get("dirty", calls[0].get("dirty"))} if cfg.get("commit") else
             {"commit": calls[0].get("commit", started["commit"]), "dirty": calls[0].get("dirty", started["dirty"])})
    commits = {c["commit"] for c in calls if c.get("commit")} | {first["commit"]}
    runfiles.write_json_atomic(path, {
        **started, **first, "commits": sorted(c for c in commits if c),
        "wall_seconds": round(sum(c["wall_seconds"] for c in calls), 2), "calls": calls})


def plan_cell(args: argparse.Namespace, task: str, method: str, options: list[str] | None = None) -> dict:
    """What the grid does with a cell now: {"state": done|new|restart|resume|extend, "out", "archived",
    "argv" (None when done), "message"} (the state on disk decides, so a retried cell resumes).
    ``options``: the cell's run options instead of ``METHODS[method]`` (``cell_argv``)."""
    out = cell_dir(args.runs_dir, args.preset, task, method)
    state = cell_state(out)
    archived = os.path.join(archive_dir_for(args.results_dir, args.preset), task, method)
    if state == "new" and os.path.exists(os.path.join(archived, "summary.json")):
        out, state = archived, "done"  # finished in an earlier clone; its run folder is not committed
    wanted = wanted_budget(args, task)
    s = {}
    if state == "done":
        with open(os.path.join(out, "summary.json")) as f:
            s = json.load(f)
        stored_every = wanted_every = None
        from metapg_jax.host.checkpoint import saved_steps

        if s["env_steps"] < wanted and out != archived and saved_steps(os.path.join(out, "checkpoints")):
            stored_every = read_json(os.path.join(out, "config.json"))["config"]["run"]["eval_every"]
            wanted_every = requested_config(args, task, method, options).run.eval_every
            if stored_every == wanted_every:
                state = "extend"  # a finished shorter run: continue it to the requested budget
    if state == "done":
        if s["env_steps"] == wanted:
            note = ""
        elif s["env_steps"] < wanted and stored_every != wanted_every:
            # An extension keeps its evaluation interval; the cell would not be evaluated where the
            # requested budget's cells are (Table 2's final window, steps-to-threshold).
            note = (f" (stored budget {s['env_steps']:,} is below the requested {wanted:,}, but its evaluation "
                    f"interval {stored_every:,} is not the {wanted_every:,} of a run at that budget, so it is "
                    f"not extended; delete it to rerun)")
        elif s["env_steps"] < wanted:
            # An archived copy (its run folder is not in this clone) or an empty checkpoints/.
            note = (f" (stored budget {s['env_steps']:,} is below the requested {wanted:,}, and no checkpoint "
                    f"to extend it from is stored; delete it to rerun)")
        else:
            note = f" (stored budget {s['env_steps']:,} is above the requested {wanted:,}; delete it to rerun)"
        from experiments import stats
        from metapg_jax.host import metric_rows, runfiles

        # From the metrics (the tables' definition), also for a cell stored before summary.json had it.
        final = stats.run_summary(*metric_rows.curves(runfiles.read_jsonl(os.path.join(out, "metrics.jsonl"))))
        message = f"done, skipped: {stats.describe_final(final)}, {s['env_steps']:,} steps{note}"
        return {"state": state, "out": out, "archived": archived, "argv": None, "message": message}
    argv = cell_argv(args, task, method, out, state, options)
    verb = f"extending from {s['env_steps']:,} to {wanted:,} steps" if state == "extend" else \
        {"resume": "resuming", "restart": "restarting (no checkpoint stored)", "new": "running"}[state]
    return {"state": state, "out": out, "archived": archived, "argv": argv,
            "message": f"{verb}: python -m experiments.run {' '.join(argv)}"}


def run_cell(args: argparse.Namespace, task: str, method: str, plan: dict) -> int:
    """Runs a planned cell (``experiments.run.main``), records it in ``reproduce.json`` and archives it when
    it finished; returns the run's exit status. Called in this process, or in a Ray worker."""
    from experiments import run as run_lib
    from metapg_jax.host import provenance

    out, argv = plan["out"], plan["argv"]
    started, t0 = provenance.record(), time.perf_counter()
    diff = provenance.uncommitted_diff() if started["dirty"] else ""
    try:
        code = run_lib.main(argv)
    except KeyboardInterrupt:  # Ctrl-C before the run's own handler is installed (e.g. while compiling)
        code = 130
    if os.path.isdir(out):
        _write_cell_record(out, argv, code, time.perf_counter() - t0, started, diff)
        archive_cell(out, plan["archived"], method, baseline_for(args.preset, args.student))
    return code


def outcome(plan: dict, code: int) -> str:
    return {0: {"resume": "resumed", "extend": "extended"}.get(plan["state"], "ran")}.get(code, f"exit {code}")


def run_grid(args: argparse.Namespace, tasks: list[str], methods: list[str]) -> tuple[int, dict]:
    """Runs the grid cell by cell; returns (exit status, {cell: what happened})."""
    status, report = 0, {}
    cells = [(t, m) for t in tasks for m in methods]
    for i, (task, method) in enumerate(cells, 1):
        tag = f"[{i}/{len(cells)}] {args.preset}/{task}/{method}"
        plan = plan_cell(args, task, method)
        print(f"{tag}: {plan['message']}", flush=True)
        if plan["argv"] is None:
            report[(task, method)] = "skipped"
            continue
        if args.dry_run:
            report[(task, method)] = f"would {plan['state']}"
            continue
        code = run_cell(args, task, method, plan)
        if code == 0 and os.path.exists(os.path.join(plan["archived"], "summary.json")):
            print(f"{tag}: finished; results archived in {plan['archived']}", flush=True)
        report[(task, method)] = outcome(plan, code)
        if code in (130, 143):  # Ctrl-C or SIGTERM: the grid stops too
            print(f"{tag}: interrupted; run the same command again to resume", file=sys.stderr, flush=True)
            return code, report
        if code == 2:
            print(f"{tag}: bad options (exit 2); stopping the grid", file=sys.stderr, flush=True)
            return 2, report
        if code:
            print(f"{tag}: stopped with exit {code}; continuing with the next cell", file=sys.stderr, flush=True)
            status = status or code
    return status, report


def _ray_cell(args: argparse.Namespace, task: str, method: str, cwd: str) -> tuple[dict, int]:
    """A cell as a Ray task: planned again from what is on disk (a task retried after its worker died
    resumes from the cell's last checkpoint), then ``run_cell``."""
    os.chdir(cwd)  # the grid's folders are relative to the driver's working directory
    plan = plan_cell(args, task, method)
    if plan["argv"] is None:
        return plan, 0
    return plan, run_cell(args, task, method, plan)


def run_grid_ray(args: argparse.Namespace, tasks: list[str], methods: list[str]) -> tuple[int, dict]:
    """Every cell that has work left as a Ray task with its CPU and GPU needs declared; returns
    (exit status, {cell: what happened}) like ``run_grid``."""
    import ray

    status, report = 0, {}
    cells = [(t, m) for t in tasks for m in methods]
    tags = {c: f"[{i}/{len(cells)}] {args.preset}/{c[0]}/{c[1]}" for i, c in enumerate(cells, 1)}
    pending = []
    for cell in cells:
        plan = plan_cell(args, *cell)
        print(f"{tags[cell]}: {plan['message'] if plan['argv'] is None else 'submitted to Ray: ' + plan['message']}",
              flush=True)
        if plan["argv"] is None:
            report[cell] = "skipped"
        else:
            pending.append(cell)
    if not pending:
        return 0, report
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    started_here = args.ray_address is None
    ray.init(address=args.ray_address, include_dashboard=False, log_to_driver=True,
             runtime_env={"env_vars": {"PYTHONPATH": os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH"))
                                                                      if p)}})
    try:
        remote = ray.remote(max_retries=args.ray_retries)(_ray_cell).options(
            num_cpus=args.ray_cpus_per_cell, num_gpus=args.ray_gpus_per_cell)
        refs = {remote.remote(args, task, method, os.getcwd()): (task, method) for task, method in pending}
        print(f"ray: {len(refs)} cell(s) on {'a local instance' if started_here else args.ray_address} "
              f"({ray.cluster_resources().get('CPU', 0):g} CPUs, {ray.cluster_resources().get('GPU', 0):g} GPUs; "
              f"{args.ray_cpus_per_cell:g} CPU and {args.ray_gpus_per_cell:g} GPU per cell)", flush=True)
        waiting = list(refs)
        try:
            while waiting:
                done, waiting = ray.wait(waiting, num_returns=1)
                cell = refs[done[0]]
                try:
                    plan, code = ray.get(done[0])
                except Exception as err:  # noqa: BLE001 - the task failed past its retries: report, go on
                    print(f"{tags[cell]}: failed on Ray: {type(err).__name__}: {str(err).splitlines()[0][:300]}",
                          file=sys.stderr, flush=True)
                    report[cell], status = "failed", status or 1
                    continue
                report[cell] = outcome(plan, code)
                if code == 0:
                    print(f"{tags[cell]}: finished; results archived in {plan['archived']}", flush=True)
                else:
                    print(f"{tags[cell]}: stopped with exit {code}", file=sys.stderr, flush=True)
                    status = status or code
        except KeyboardInterrupt:  # the tasks get Ctrl-C too: each checkpoints its chunk in flight and stops
            for ref in waiting:
                ray.cancel(ref)
            print("interrupted; run the same command again to resume", file=sys.stderr, flush=True)
            return 130, report
    finally:
        ray.shutdown()
    return status, report


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    mujoco = args.physics == "mujoco"
    other = args.student != "ddpg"
    if args.runs_dir is None:
        args.runs_dir = f"runs/reproduce-{args.student}" if other else MUJOCO_RUNS if mujoco else "runs/reproduce"
    if args.results_dir is None:
        args.results_dir = f"results/{args.student}" if other else MUJOCO_RESULTS if mujoco else "results"
    try:
        tasks = parse_list(args.tasks, TASKS, "task")
        if mujoco and args.source != "gymnasium":
            raise ValueError(f"--physics=mujoco steps gymnasium's models; source {args.source!r} has only MJX")
        grid_methods = methods_for(args.student)
        methods = parse_list(args.methods or ",".join(grid_methods), grid_methods, "method")
        if args.seeds <= 0:
            raise ValueError(f"--seeds must be positive, got {args.seeds}")
        if args.steps is not None and args.steps <= 0:
            raise ValueError(f"--steps must be positive, got {args.steps}")
        for item in args.overrides:
            if "=" not in item:
                raise ValueError(f"--set expects GROUP.FIELD=VALUE, got {item!r}")
        if args.launcher == "ray" and not args.artefacts_only and not args.dry_run:
            try:
                import ray  # noqa: F401
            except ImportError:
                raise ValueError("--launcher ray needs Ray: pip install -e \".[ray]\"") from None
        if args.ray_cpus_per_cell < 0 or args.ray_gpus_per_cell < 0 or args.ray_retries < 0:
            raise ValueError("--ray-cpus-per-cell, --ray-gpus-per-cell and --ray-retries must be >= 0")
        if args.tensorboard and not args.artefacts_only:
            from metapg_jax.host import tb_events

            tb_events.require_tensorboard()
        if not args.artefacts_only:
            # Every cell's config before the first one trains: a budget that one method's cycle does not
            # divide, or a bad --set, stops the grid here rather than after the cells before it have run.
            for task in tasks:
                for method in methods:
                    if finished_at_budget(args, task, method):
                        continue  # skipped by run_grid whatever its config would be at this budget
                    try:
                        requested_config(args, task, method)
                    except ValueError as err:
                        raise ValueError(f"{task}/{method}: {err}") from None
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    status, report = 0, {}
    if not args.artefacts_only:
        launch = run_grid_ray if args.launcher == "ray" and not args.dry_run else run_grid
        status, report = launch(args, tasks, methods)
        counts = {}
        for v in report.values():
            counts[v] = counts.get(v, 0) + 1
        print("grid: " + (", ".join(f"{n} {k}" for k, n in sorted(counts.items())) or "nothing to do"), flush=True)
    if args.dry_run:
        return status
    manifest = build_all(
        args.runs_dir, args.results_dir, args.preset, embedding=args.embedding,
        visitation_tasks=args.visitation_task, student=args.student,
        extra_provenance={"reproduce_argv": sys.argv[1:] if argv is None else list(argv),
                          "requested": {"tasks": tasks, "methods": methods, "seeds": args.seeds, "seed": args.seed,
                                        "steps": args.steps, "overrides": args.overrides},
                          "grid_wall_seconds": round(time.perf_counter() - t0, 2)})
    out = results_dir_for(args.results_dir, args.preset)
    print(f"artefacts: {len(manifest['files'])} files in {out} ({len(manifest['cells'])} stored cells, "
          f"{len(manifest['not_run'])} not run): {', '.join(manifest['files'])}", flush=True)
    return status


if __name__ == "__main__":
    sys.exit(main())
