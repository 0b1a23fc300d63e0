"""What a grid's cells with work left would cost, measured before they run (``--dry-run`` of
``experiments.benchmark``; ``experiments.reproduce`` and ``experiments.screen`` with ``--estimate``): each method
with work left runs ``experiments.run`` in a subprocess for a few chunks of ``--calibration-steps`` env steps on
one task (its real config otherwise: seeds, networks, replay capacity; a cold compile), and each other task with
work left runs its student's Gaussian noise (``GAUSSIAN``) the same way; a cell's estimate is the calibration
task's compile time and per-step time of its method, scaled by the task's over the calibration task's for the
Gaussian noise, times its remaining steps; CPU time is that times the method's CPU utilisation during its
calibration. A method is calibrated once, on the calibration task in the form of its last cell in the plan (a screen variant
whose change differs by task is timed in one task's form). The calibration runs share the machine with whatever else
runs on it: an estimate made beside other work leans high."""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

from experiments.grid.methods import GAUSSIAN, METHODS
from experiments.grid.spec import CellSpec
from experiments.training import grid_cells
from experiments.training.grid_cells import Cell
from metapg_jax.host.terminal import duration

CALIBRATION_STEPS = 3000
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def add_estimate_options(p: argparse.ArgumentParser, by_default: bool) -> None:
    """``--no-calibrate`` (``by_default``: a dry run estimates unless told not to) or ``--estimate`` (it estimates
    only when asked), ``--calibration-task`` and ``--calibration-steps``."""
    if by_default:
        p.add_argument("--no-calibrate", action="store_true",
                       help="--dry-run without the calibration runs (no estimate)")
    else:
        p.add_argument("--estimate", dest="no_calibrate", action="store_false", default=True,
                       help="--dry-run with calibration runs: each cell's estimated CPU and wall time "
                            "(experiments.grid.estimate)")
    p.add_argument("--calibration-task", default=None,
                   help="the task every method is calibrated on (default hopper if planned, else the first task)")
    p.add_argument("--calibration-steps", type=int, default=CALIBRATION_STEPS,
                   help=f"env steps per seed of each timed calibration chunk, rounded up to whole cycles "
                        f"(default {CALIBRATION_STEPS:,}; at most the cell's evaluation interval)")


def check_estimate_options(a: argparse.Namespace, tasks: list[str]) -> None:
    if a.calibration_task is not None and a.calibration_task not in tasks:
        raise ValueError(f"--calibration-task {a.calibration_task!r} is not one of the planned tasks")
    if a.calibration_steps <= 0:
        raise ValueError(f"--calibration-steps must be positive, got {a.calibration_steps}")


def calibration_run(spec: CellSpec, name: str, chunk_steps: int) -> dict:
    """Times a short run of the cell's real config (seeds, networks, replay capacity, evaluation episodes) in an
    ``experiments.run`` subprocess with a cold compile: a few chunks of ``chunk_steps`` env steps (whole cycles,
    at most the cell's evaluation interval) after any random warm-up. Returns its compile seconds, the seconds per
    env step of the steady chunks (their median; each chunk ends with one evaluation, so the evaluations weigh
    more here than in a run that evaluates less often), and its CPU utilisation (CPU seconds / wall seconds of
    the subprocess); ``ValueError`` (one line) when the run fails. ``name``: the cell's grid method."""
    cfg = spec.config()
    cycle = cfg.steps_per_cycle
    k = min(cfg.run.eval_every, -(-chunk_steps // cycle) * cycle)
    warm = -(-cfg.run.warmup_steps // k)  # chunks that act at random before the first update
    chunks = warm + 3
    cal = dataclasses.replace(spec, steps=chunks * k, overrides=(
        *spec.overrides, f"run.eval_every={k}", f"run.buffer_size={cfg.buffer_capacity}"))
    with tempfile.TemporaryDirectory(prefix="metapg-calibration-") as tmp:
        out = os.path.join(tmp, "run")
        argv = cal.argv() + ["--out", out, "--compile-cache=off", "--quiet", "--no-plot"]
        before, t0 = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (ROOT, os.environ.get("PYTHONPATH")) if p)}
        proc = subprocess.run([sys.executable, "-m", "experiments.run", *argv], capture_output=True, text=True,
                              env=env)
        wall, after = time.perf_counter() - t0, resource.getrusage(resource.RUSAGE_CHILDREN)
        if proc.returncode:
            lines = (proc.stderr or proc.stdout).strip().splitlines() or [f"exit {proc.returncode}"]
            raise ValueError(f"the calibration run of {spec.task}/{name} failed: {lines[-1]}")
        with open(os.path.join(out, "summary.json")) as f:
            summary = json.load(f)
        seconds = {}
        with open(os.path.join(out, "metrics.jsonl")) as f:
            for line in f:
                row = json.loads(line)
                seconds.setdefault(row["chunk"], row["chunk_seconds"])
    steady = [seconds[c] for c in sorted(seconds)][warm + 1:]
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    return {"task": spec.task, "method": name, "chunk_steps": k, "chunks": chunks, "seeds": spec.seeds,
            "compile_seconds": float(summary["compile_seconds"]),
            "seconds_per_step": statistics.median(steady) / k, "wall_seconds": round(wall, 2),
            "cpu_seconds": round(cpu, 2), "cpu_utilisation": cpu / wall if wall > 0 else 1.0}


def remaining_steps(cell: Cell, plan_: dict) -> int:
    """The env steps per seed a planned cell still has to run: the budget, less a resumed cell's checkpointed
    chunks or an extended cell's stored steps."""
    from metapg_jax.host.checkpoint import saved_steps

    budget = cell.spec.budget()
    if plan_["state"] == "resume":
        every = cell.spec.config().run.eval_every
        return max(0, budget - saved_steps(os.path.join(plan_["out"], "checkpoints"))[-1] * every)
    if plan_["state"] == "extend":
        with open(os.path.join(plan_["out"], "summary.json")) as f:
            return max(0, budget - json.load(f)["env_steps"])
    return budget


def calibrate(a: argparse.Namespace, tasks: list[str], todo: list[tuple[Cell, dict]],
              run=None) -> tuple[dict, dict, list[str]]:
    """({cell key: {"wall_seconds", "cpu_seconds"}} estimated for every cell in ``todo`` (cells with work left and
    their plans), {name: calibration measurement}, failures). The entries are calibrated on the calibration task;
    every other task with work left is scaled by its student's Gaussian noise there over the calibration task
    (``run``: default ``calibration_run``)."""
    run = run or calibration_run
    cal_task = a.calibration_task or next(t for t in ("hopper", *tasks) if t in tasks)
    wanted = {}
    for cell, _ in todo:
        s = cell.spec.student
        wanted[(s, cal_task, cell.name)] = dataclasses.replace(cell.spec, task=cal_task)
        if cell.task != cal_task:
            base = GAUSSIAN[s]
            for t in (cal_task, cell.task):
                wanted[(s, t, base)] = dataclasses.replace(cell.spec, task=t, method=METHODS[base])
    measured, failures = {}, []
    for i, ((s, t, m), spec) in enumerate(wanted.items(), 1):
        print(f"calibrating [{i}/{len(wanted)}] {s}/{t}/{m} ...", flush=True)
        try:
            measured[(s, t, m)] = run(spec, m, a.calibration_steps)
        except ValueError as err:
            failures.append(str(err))
            print(f"  {err}", file=sys.stderr, flush=True)
            continue
        r = measured[(s, t, m)]
        print(f"  compile {r['compile_seconds']:.1f} s, {r['seconds_per_step'] * 1000:.2f} ms per env step of "
              f"{r['seeds']} seeds, CPU utilisation {r['cpu_utilisation']:.2f}", flush=True)
    estimates = {}
    for cell, plan_ in todo:
        s = cell.spec.student
        base = GAUSSIAN[s]
        own = measured.get((s, cal_task, cell.name))
        scale = measured.get((s, cell.task, base)), measured.get((s, cal_task, base))
        if own is None or (cell.task != cal_task and None in scale):
            continue
        ratio = (lambda k: 1.0) if cell.task == cal_task else (lambda k: scale[0][k] / scale[1][k])
        wall = (own["compile_seconds"] * ratio("compile_seconds")
                + remaining_steps(cell, plan_) * own["seconds_per_step"] * ratio("seconds_per_step"))
        estimates[cell.key] = {"wall_seconds": wall, "cpu_seconds": wall * own["cpu_utilisation"]}
    return estimates, {"/".join(k): v for k, v in measured.items()}, failures


def dry_run(a: argparse.Namespace, tasks: list[str], cells: list[Cell]) -> int:
    """Prints every cell's state and command, and (unless ``--no-calibrate``) its estimated time and the total;
    returns 1 when every calibration run failed, else 0."""
    plans = [(cell, grid_cells.plan_cell(cell)) for cell in cells]
    todo = [(c, p) for c, p in plans if p["argv"] is not None]
    estimates, failures = {}, []
    if todo and not a.no_calibrate:
        estimates, _, failures = calibrate(a, tasks, todo)
    counts = {}
    for i, (cell, p) in enumerate(plans, 1):
        counts[p["state"]] = counts.get(p["state"], 0) + 1
        line = f"[{i}/{len(plans)}] {cell.tag}: {p['message']}"
        if cell.key in estimates:
            e = estimates[cell.key]
            line += f"\n    estimated: {duration(e['cpu_seconds'])} CPU, {duration(e['wall_seconds'])} wall"
        print(line, flush=True)
    print("plan: " + ", ".join(f"{n} {k}" for k, n in sorted(counts.items())), flush=True)
    if not todo:
        print("estimated: nothing to run", flush=True)
    elif a.no_calibrate:
        print(f"estimated: not calibrated; {len(todo)} cells with work left", flush=True)
    else:
        cpu = sum(e["cpu_seconds"] for e in estimates.values())
        wall = sum(e["wall_seconds"] for e in estimates.values())
        missing = len(todo) - len(estimates)
        print(f"estimated total: {duration(cpu)} CPU, {duration(wall)} wall one cell at a time on this machine "
              f"({os.cpu_count()} CPUs)" + (f"; {missing} cells without an estimate (calibration failed)"
                                                     if missing else ""), flush=True)
    return 1 if failures and not estimates else 0
