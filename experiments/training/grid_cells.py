"""A grid's cells, as ``experiments.reproduce``, ``experiments.screen`` and ``experiments.benchmark`` run them:
each cell's folder and state (new, resume, extend, done), its ``experiments.run`` command line, the plan checked
before the first cell runs, the run itself with its ``reproduce.json`` record (commit, dirty diff, wall and CPU
time) and its archive; cell by cell here or as Ray tasks (``run_cells``, ``run_cells_ray``: cells that may each
carry their own grid options, e.g. one student's per cell; ``validate_cells``: every cell checked before any runs)."""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time
from typing import NamedTuple

from experiments.analysis.cells import archive_cell, archive_dir_for, read_json
from experiments.grid.methods import METHODS, task_folder
from experiments.grid.spec import CellSpec, GridRun, GridSpec, Method
from metapg_jax.host.runner import Signals, Stopped
from metapg_jax.host.terminal import duration


class Cell(NamedTuple):
    """One cell to plan and run: where its grid keeps it and how (``grid``: ``experiments.grid.spec.GridRun``), its
    run (``spec``, typed data: ``CellSpec``), the name of its folder (the grid method or the variant); ``key``: how
    the report returned by ``run_cells`` names it; ``tag``: how the progress lines name it."""

    grid: GridRun
    spec: CellSpec
    name: str
    key: tuple = ()
    tag: str = ""

    @property
    def task(self) -> str:
        return self.spec.task


def grid_cell(grid: GridRun, spec: GridSpec, task: str, name: str, method: Method | None = None,
              key: tuple | None = None, tag: str | None = None) -> Cell:
    """A grid's cell of ``task`` and the grid method ``name`` (``METHODS[name]`` unless ``method`` is given), named
    (task, name) in the report and ``<preset>/<task>/<name>`` in the lines unless ``key``/``tag`` say otherwise."""
    return Cell(grid, spec.cell(task, METHODS[name] if method is None else method), name,
                (task, name) if key is None else key, f"{grid.preset}/{task}/{name}" if tag is None else tag)


def cell_dir(runs_dir: str, preset: str, task: str, method: str) -> str:
    return os.path.join(runs_dir, preset, task_folder(task), method)


def run_dir(cell: Cell) -> str:
    """The cell's run folder: ``<runs-dir>/<preset>/<task>/<name>``."""
    return cell_dir(cell.grid.runs_dir, cell.grid.preset, cell.task, cell.name)


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


def finished_at_budget(cell: Cell) -> bool:
    """Whether the cell's run folder or its archived copy finished at (at least) the requested budget."""
    wanted = cell.spec.budget()
    for path in (run_dir(cell), archived_dir(cell)):
        summary = read_json(os.path.join(path, "summary.json"))
        if summary and summary["env_steps"] >= wanted:
            return True
    return False


def archived_dir(cell: Cell) -> str:
    """Where a finished cell is archived: ``<results>/cells/<task>/<name>`` (``cells.archive_dir_for``)."""
    return os.path.join(archive_dir_for(cell.grid.results_dir, cell.grid.preset), task_folder(cell.task), cell.name)


def cell_argv(cell: Cell, out: str, state: str) -> list[str]:
    """The explicit ``experiments.run`` options of a cell (the same for a fresh start and a resume; an
    extension names the new budget): its run's (``CellSpec.argv``), then how the grid runs it, then the folder."""
    argv = cell.spec.argv(explicit_steps=state == "extend") + cell.grid.run_options()
    if state in ("resume", "extend"):
        argv += ["--resume", out]
    else:
        argv += ["--out", out] + (["--overwrite"] if state == "restart" else [])
    return argv


def stored_elsewhere(cell: Cell, path: str) -> str:
    """Why a finished run folder or archived copy is not this cell's run ('' when it is): it was run with other
    seeds or another base seed (its numbers would be taken for the requested cell's)."""
    stored = read_json(os.path.join(path, "config.json")).get("run_args") or {}
    changed = [f"{k} {stored[k]} (requested {getattr(cell.spec, k)})" for k in ("seeds", "seed")
               if k in stored and stored[k] != getattr(cell.spec, k)]
    return f"stored with {', '.join(changed)}" if changed else ""


def validate_cells(cells: list[Cell]) -> None:
    """Every cell's config before the first one trains: a budget that one method's cycle does not divide, a bad
    ``--set``, a task the engine cannot step, or a finished cell stored with other seeds stops the grid here
    (``ValueError``, one line naming the cell) rather than after the cells before it have run."""
    for cell in cells:
        for path in (run_dir(cell), archived_dir(cell)):
            why = os.path.exists(os.path.join(path, "summary.json")) and stored_elsewhere(cell, path)
            if why:
                raise ValueError(f"{cell.tag}: {path} holds a finished run {why}; move it "
                                 "away or give the grid other --runs-dir/--results-dir")
        if finished_at_budget(cell):
            continue  # skipped whatever its config would be at this budget
        try:
            cell.spec.config()
        except ValueError as err:
            raise ValueError(f"{cell.tag}: {err}") from None


def write_cell_record(out: str, argv: list[str], status: int, seconds: float, started: dict,
                       diff: str = "", cpu_seconds: float | None = None) -> None:
    """``reproduce.json`` in the cell: commit, machine, command, status and accumulated wall time (and CPU time:
    ``cpu_seconds``, the process's user + system time over the call, all its threads; the top-level sum counts
    the calls that recorded it, ``cpu_seconds_calls`` of them); a call
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
    if cpu_seconds is not None:
        call["cpu_seconds"] = round(cpu_seconds, 2)
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
    cpu = [c["cpu_seconds"] for c in calls if "cpu_seconds" in c]
    runfiles.write_json_atomic(path, {
        **started, **first, "commits": sorted(c for c in commits if c),
        "wall_seconds": round(sum(c["wall_seconds"] for c in calls), 2),
        **({"cpu_seconds": round(sum(cpu), 2), "cpu_seconds_calls": len(cpu)} if cpu else {}), "calls": calls})


def plan_cell(cell: Cell) -> dict:
    """What the grid does with a cell now: {"state": done|new|restart|resume|extend, "out", "archived",
    "argv" (None when done), "message"} (the state on disk decides, so a retried cell resumes)."""
    out = run_dir(cell)
    state = cell_state(out)
    archived = archived_dir(cell)
    if state == "new" and os.path.exists(os.path.join(archived, "summary.json")):
        out, state = archived, "done"  # finished in an earlier clone; its run folder is not committed
    wanted = cell.spec.budget()
    s = {}
    if state == "done":
        with open(os.path.join(out, "summary.json")) as f:
            s = json.load(f)
        stored_every = wanted_every = None
        from metapg_jax.host.checkpoint import saved_steps

        if s["env_steps"] < wanted and out != archived and saved_steps(os.path.join(out, "checkpoints")):
            stored_every = read_json(os.path.join(out, "config.json"))["config"]["run"]["eval_every"]
            wanted_every = cell.spec.config().run.eval_every
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
        why = stored_elsewhere(cell, out)
        if why:
            note += f" (not this grid's run: {why})"
        from experiments.analysis import stats
        from metapg_jax.host import metric_rows, runfiles

        # From the metrics (the tables' definition), also for a cell stored before summary.json had it.
        final = stats.run_summary(*metric_rows.curves(runfiles.read_jsonl(os.path.join(out, "metrics.jsonl"))))
        message = f"done, skipped: {stats.describe_final(final)}, {s['env_steps']:,} steps{note}"
        return {"state": state, "out": out, "archived": archived, "argv": None, "message": message}
    argv = cell_argv(cell, out, state)
    verb = f"extending from {s['env_steps']:,} to {wanted:,} steps" if state == "extend" else \
        {"resume": "resuming", "restart": "restarting (no checkpoint stored)", "new": "running"}[state]
    return {"state": state, "out": out, "archived": archived, "argv": argv,
            "message": f"{verb}: python -m experiments.run {shlex.join(argv)}"}


def run_cell(cell: Cell, plan: dict) -> int:
    """Runs a planned cell (``experiments.run.main``), records it in ``reproduce.json`` and archives it when
    it finished; returns the run's exit status. Called in this process, or in a Ray worker."""
    from experiments import run as run_lib
    from metapg_jax.host import provenance

    out, argv = plan["out"], plan["argv"]
    started, t0, cpu0 = provenance.record(), time.perf_counter(), time.process_time()
    diff = provenance.uncommitted_diff() if started["dirty"] else ""
    try:
        code = run_lib.main(argv)
    except KeyboardInterrupt:  # Ctrl-C before the run's own handler is installed (not under ``run_cells``)
        code = 130
    if os.path.isdir(out):
        write_cell_record(out, argv, code, time.perf_counter() - t0, started, diff, time.process_time() - cpu0)
        archive_cell(out, plan["archived"], cell.name, cell.grid.baseline)
    return code


def outcome(plan: dict, code: int) -> str:
    return {0: {"resume": "resumed", "extend": "extended"}.get(plan["state"], "ran")}.get(code, f"exit {code}")


def run_cells(cells: list[Cell], dry_run: bool = False) -> tuple[int, dict]:
    """Runs the cells one after another in this process (each planned from what is on disk when its turn comes);
    returns (exit status, {cell key: what happened}). ``dry_run``: plan and print only.

    Ctrl-C stops the grid wherever it comes (``runner.Signals``): during a cell's run, the run checkpoints its
    chunk in flight; while a run is set up, after its first chunk; while a cell is planned, recorded or archived,
    before the next cell starts; exit 130. SIGTERM stops the grid with exit 143: during a cell's run, after the
    run checkpointed its chunk in flight within its grace (``--term-grace``) or at once where that cannot be met;
    a second Ctrl-C stops a run at once (130); a stop that comes while a cell is recorded or archived waits for
    that to end."""
    status, report, walls = 0, {}, []
    with Signals("the grid stops at the next checkpoint or before the next cell") as signals:
        for i, cell in enumerate(cells, 1):
            tag = f"[{i}/{len(cells)}] {cell.tag}"
            try:
                signals.check()
                if signals.requested:
                    print(f"{tag}: not started (interrupted); run the same command again to go on",
                          file=sys.stderr, flush=True)
                    return 130, report
                t0 = time.perf_counter()
                with signals.holding():
                    code = _run_in_turn(cell, tag, dry_run, report)
                if code == 0 and report[cell.key] in ("ran", "resumed", "extended"):
                    walls.append(time.perf_counter() - t0)
                    if i < len(cells):
                        print(progress_line(walls, len(cells) - i), flush=True)
                signals.check()
            except Stopped as err:  # outside the runs' own loops
                print(f"{tag}: stopped by {err.who}; run the same command again to go on", file=sys.stderr,
                      flush=True)
                return err.status, report
            if code in (130, 143):  # Ctrl-C or SIGTERM: the grid stops too
                print(f"{tag}: interrupted; run the same command again to resume", file=sys.stderr, flush=True)
                return code, report
            if code == 2:
                print(f"{tag}: bad options (exit 2); stopping the grid", file=sys.stderr, flush=True)
                return 2, report
            if code:
                print(f"{tag}: stopped with exit {code}; continuing with the next cell", file=sys.stderr,
                      flush=True)
                status = status or code
    return status, report


def progress_line(walls: list[float], left: int) -> str:
    """How far a grid has come: the cells run in this call, their mean wall time, and what the ``left`` cells
    after this one would take at that mean (an upper bound where some of them are done already)."""
    mean = sum(walls) / len(walls)
    return (f"grid: {len(walls)} cell(s) run in this call, {duration(mean)} each on average; {left} cell(s) after "
            f"this one, at most about {duration(left * mean)} more at that rate")


def _run_in_turn(cell: Cell, tag: str, dry_run: bool, report: dict) -> int:
    """``run_cells``'s one cell: planned, run (unless done or ``dry_run``) and reported; its exit status."""
    plan = plan_cell(cell)
    print(f"{tag}: {plan['message']}", flush=True)
    if plan["argv"] is None or dry_run:
        report[cell.key] = "skipped" if plan["argv"] is None else f"would {plan['state']}"
        return 0
    code = run_cell(cell, plan)
    if code == 0 and os.path.exists(os.path.join(plan["archived"], "summary.json")):
        print(f"{tag}: finished; results archived in {plan['archived']}", flush=True)
    report[cell.key] = outcome(plan, code)
    return code


def _ray_cell(cell: Cell, cwd: str) -> tuple[dict, int]:
    """A cell as a Ray task: planned again from what is on disk (a task retried after its worker died
    resumes from the cell's last checkpoint), then ``run_cell``."""
    os.chdir(cwd)  # the grid's folders are relative to the driver's working directory
    plan = plan_cell(cell)
    if plan["argv"] is None:
        return plan, 0
    return plan, run_cell(cell, plan)


def run_cells_ray(cells: list[Cell], launcher: argparse.Namespace) -> tuple[int, dict]:
    """Every cell that has work left as a Ray task with its CPU and GPU needs declared (``launcher``'s
    ``--ray-*`` options, ``experiments.reproduce``'s); returns (exit status, {cell key: what happened}) like
    ``run_cells``."""
    import ray

    status, report = 0, {}
    tags = {cell.key: f"[{i}/{len(cells)}] {cell.tag}" for i, cell in enumerate(cells, 1)}
    pending = []
    for cell in cells:
        plan = plan_cell(cell)
        print(f"{tags[cell.key]}: "
              f"{plan['message'] if plan['argv'] is None else 'submitted to Ray: ' + plan['message']}", flush=True)
        if plan["argv"] is None:
            report[cell.key] = "skipped"
        else:
            pending.append(cell)
    if not pending:
        return 0, report
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # the repository
    started_here = launcher.ray_address is None
    ray.init(address=launcher.ray_address, include_dashboard=False, log_to_driver=True,
             runtime_env={"env_vars": {"PYTHONPATH": os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH"))
                                                                      if p)}})
    try:
        remote = ray.remote(max_retries=launcher.ray_retries)(_ray_cell).options(
            num_cpus=launcher.ray_cpus_per_cell, num_gpus=launcher.ray_gpus_per_cell)
        refs = {remote.remote(cell, os.getcwd()): cell.key for cell in pending}
        print(f"ray: {len(refs)} cell(s) on {'a local instance' if started_here else launcher.ray_address} "
              f"({ray.cluster_resources().get('CPU', 0):g} CPUs, {ray.cluster_resources().get('GPU', 0):g} GPUs; "
              f"{launcher.ray_cpus_per_cell:g} CPU and {launcher.ray_gpus_per_cell:g} GPU per cell)", flush=True)
        waiting = list(refs)
        try:
            while waiting:
                done, waiting = ray.wait(waiting, num_returns=1)
                key = refs[done[0]]
                try:
                    plan, code = ray.get(done[0])
                except Exception as err:  # noqa: BLE001 - the task failed past its retries: report, go on
                    print(f"{tags[key]}: failed on Ray: {type(err).__name__}: {str(err).splitlines()[0][:300]}",
                          file=sys.stderr, flush=True)
                    report[key], status = "failed", status or 1
                    continue
                report[key] = outcome(plan, code)
                if code == 0:
                    print(f"{tags[key]}: finished; results archived in {plan['archived']}", flush=True)
                else:
                    print(f"{tags[key]}: stopped with exit {code}", file=sys.stderr, flush=True)
                    status = status or code
        except KeyboardInterrupt:  # the tasks get Ctrl-C too: each checkpoints its chunk in flight and stops
            for ref in waiting:
                ray.cancel(ref)
            print("interrupted; run the same command again to resume", file=sys.stderr, flush=True)
            return 130, report
    finally:
        ray.shutdown()
    return status, report
