"""A grid's cells, as ``experiments.reproduce`` and ``experiments.screen`` run them: each cell's folder and state
(new, resume, extend, done), its ``experiments.run`` command line, the plan checked before the first cell runs,
the run itself with its ``reproduce.json`` record (commit, dirty diff, wall time) and its archive; cell by cell
here or as Ray tasks."""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

from experiments.build.cells import archive_cell, archive_dir_for, read_json
from experiments.build.grid import METHODS, baseline_for
from experiments.training.args import RUN_ARGS


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
    if args.student != RUN_ARGS["student"]:  # named when it is not experiments.run's default
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
    from experiments.training import args as training_args

    parsed = run_lib.build_parser().parse_args(cell_argv(args, task, method, os.devnull, "new", options))
    return training_args.config_from_run_args(training_args.run_args(parsed))


def write_cell_record(out: str, argv: list[str], status: int, seconds: float, started: dict,
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
    # A call killed before it wrote its record (machine shut down, SIGKILL) still started the cell: config.json's
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
        from experiments.build import stats
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
        write_cell_record(out, argv, code, time.perf_counter() - t0, started, diff)
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
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # the repository
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
