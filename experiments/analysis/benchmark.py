"""The exploration benchmark's artefacts (``experiments.benchmark``), from stored cells: per task every (student,
strategy) cell's final return with its corrected verdict against the student's baseline (its Gaussian noise
unless a reference chosen in advance is named), the
aggregate over the tasks (Agarwal et al., 2021), sample-efficiency curves, the cost of every cell, ``README.md``
and ``manifest.json``.

A benchmark *entry* is a student and one of its strategies (``Entry``: a grid method of
``experiments.grid.methods.STRATEGIES``). Each student's cells are a grid of their own, laid out as
``experiments.reproduce`` lays out a grid (``<runs>/<student>/paper/<task>/<method>``, archived in
``<results>/<student>/cells/<task>/<method>``), so that the same strategy (the paper's teacher) can be an entry of
two students without their folders colliding. Everything is read from the stored cells (``experiments.analysis.cells``);
a cell without a finished run is shown as "not run" (or "incomplete"), never estimated.

Statistics: the per-cell numbers and the verdicts are ``experiments.analysis.tables``' (``table2_rows``,
``verdict_family``) and ``experiments.analysis.stats``' (``judge_family``: Welch tests Holm-corrected within a family,
'equivalent' only by the TOST of the declared margin); the aggregate is ``experiments.aggregate``'s (IQM, mean,
optimality gap, probability of improvement, performance profiles; stratified bootstrap intervals).
"""

from __future__ import annotations

import dataclasses
import glob
import json
import os
from typing import Sequence

import numpy as np

from experiments.analysis import cells, stats, tables
from experiments.grid.methods import (METHOD_NAMES, NAMED_ONLY, STRATEGIES, STUDENT_BASELINES, STUDENT_NAMES,
                                    noise_methods, task_folder)

# The preset of every student's grid (a grid method with a preset of its own, the tuned teacher, keeps it).
PRESET = "paper"
STUDENT_COLORS = {"td3": "tab:blue", "sac": "tab:red", "ddpg": "tab:green"}
BEST_NOISE_RULE = (
    "the best fixed noise of a student is the strategy with the highest IQM among its strategies that explore with "
    "noise (not a learned teacher), chosen on the same seeds that the probabilities of improvement are computed "
    "on, so P(X > best fixed noise) is optimistic for the best noise (a choice made in advance on other seeds, "
    "as the learned-exploration judgement makes it, would not be)")
CURVES_DEFINITION = (
    "per evaluation point: the IQM of the seeds' normalised evaluation returns (each evaluation: the mean return of "
    "`run.eval_episodes` deterministic episodes) pooled over the aggregate's tasks, at the env steps where every "
    "cell of the aggregate was evaluated; band: 95% stratified percentile bootstrap over the seeds of each task "
    "({reps:,} replicates, generator seed {seed})")


@dataclasses.dataclass(frozen=True)
class Entry:
    """A benchmark entry: a student and one of its strategies (a grid method)."""

    student: str
    method: str
    baseline: str = ""  # the student's reference, every other entry of the student is judged against it

    def __post_init__(self):
        if not self.baseline:  # default: the student's Gaussian noise (``STUDENT_BASELINES``)
            object.__setattr__(self, "baseline", STUDENT_BASELINES[self.student])

    @property
    def key(self) -> str:
        """How the aggregate's JSON names the entry: ``<student>/<method>``."""
        return f"{self.student}/{self.method}"

    @property
    def label(self) -> str:
        """E.g. 'TD3 (OU noise)', 'TD3 + Meta (independent)'."""
        name, student = METHOD_NAMES.get(self.method, self.method), STUDENT_NAMES.get(self.student, self.student)
        return name if name.startswith(student) else f"{student} + {name}"

    @property
    def noise(self) -> bool:
        """Whether the strategy explores with fixed noise (not a learned teacher)."""
        return bool(noise_methods([self.method]))


def entries_for(students: Sequence[str], strategies: Sequence[str] | None = None,
                baselines: dict[str, str] | None = None) -> list[Entry]:
    """The entries of ``students`` (``STRATEGIES`` order, then ``NAMED_ONLY``'s), restricted to ``strategies`` (grid
    methods) when given, else ``STRATEGIES``' only. Each student's baseline is always one of them (every other
    entry is judged against it): ``baselines[student]`` where given (a reference chosen in advance, e.g. the best
    fixed noise of an earlier benchmark), else its Gaussian noise. ``ValueError`` for a baseline that is not one of
    the student's strategies."""
    baselines = dict(baselines or {})
    for s, m in baselines.items():
        if s not in students:
            raise ValueError(f"baseline {s}={m}: {s!r} is not one of the planned students ({', '.join(students)})")
        if m not in (*STRATEGIES[s], *NAMED_ONLY.get(s, ())):
            raise ValueError(f"baseline {s}={m}: {m!r} is not a strategy of {s}; valid: "
                             + ", ".join((*STRATEGIES[s], *NAMED_ONLY.get(s, ()))))
    out = []
    for s in students:
        base = baselines.get(s, STUDENT_BASELINES[s])
        chosen = [m for m in STRATEGIES[s] if strategies is None or m in strategies or m == base]
        chosen += [m for m in NAMED_ONLY.get(s, ()) if strategies is not None and m in strategies or m == base]
        out += [Entry(s, m, base) for m in chosen]
    return out


def baselines_of(entries: Sequence[Entry]) -> dict[str, str]:
    """{student: its baseline method} of ``entries``."""
    return {e.student: e.baseline for e in entries}


def student_dirs(runs_dir: str, results_dir: str, student: str) -> tuple[str, str]:
    """A student's grid folders: (``<runs>/<student>``, ``<results>/<student>``), laid out as experiments.reproduce's
    ``--runs-dir`` and ``--results-dir`` (``<runs>/<student>/paper/<task>/<method>``, archive
    ``<results>/<student>/cells/<task>/<method>``)."""
    return os.path.join(runs_dir, student), os.path.join(results_dir, student)


def collect(runs_dir: str, results_dir: str, entries: Sequence[Entry], tasks: Sequence[str],
            preset: str = PRESET) -> dict:
    """{(student, task, method): RunResult} of the stored cells of ``preset``'s grid, every finished run folder
    first (re)archived (``cells.archive_cell``); a cell without a finished run folder is read from the archive."""
    out = {}
    for student in dict.fromkeys(e.student for e in entries):
        methods = [e.method for e in entries if e.student == student]
        runs, results = student_dirs(runs_dir, results_dir, student)
        archive = cells.archive_dir_for(results, preset)
        for task in tasks:
            for method in methods:
                cells.archive_cell(os.path.join(runs, preset, task_folder(task), method),
                                   os.path.join(archive, task_folder(task), method), method, STUDENT_BASELINES[student])
        found = cells.collect(os.path.join(runs, preset), tasks, methods, archive_dir=archive)
        out.update({(student, t, m): r for (t, m), r in found.items()})
    return out


def read_task_tables(results_dir: str) -> dict[str, dict]:
    """{task: its table} of a built benchmark's ``tasks/*.json`` (each finished cell's row with its per-seed final
    returns), in file name order; {} where there are none."""
    out = {}
    for path in sorted(glob.glob(os.path.join(results_dir, "tasks", "*.json"))):
        with open(path) as f:
            table = json.load(f)
        out[table["task"]] = table
    return out


def student_rows(results: dict, entries: Sequence[Entry], tasks: Sequence[str]) -> dict[str, list[dict]]:
    """{student: ``tables.table2_rows`` of its cells} (per task and method: status, mean, std, CI, per-seed finals)."""
    out, bases = {}, baselines_of(entries)
    for student in bases:
        methods = [e.method for e in entries if e.student == student]
        mine = {(t, m): r for (s, t, m), r in results.items() if s == student}
        out[student] = tables.table2_rows(mine, tasks, methods, bases[student])
    return out


def verdicts(rows: dict[str, list[dict]], entries: Sequence[Entry], anchors: dict | None) -> dict[str, dict]:
    """{student: its family of corrected verdicts} (``tables.verdict_family``): every other strategy of the student
    against its baseline on every task where both finished at the same budget, Holm-corrected within the family;
    equivalence within ``stats.EQUIVALENCE_MARGIN`` of the task's anchors' range."""
    out, bases = {}, baselines_of(entries)
    for student, student_rows_ in rows.items():
        base = bases[student]
        others = [e.method for e in entries if e.student == student and e.method != base]
        out[student] = tables.verdict_family(student_rows_, base, others, anchors)
    return out


def combined_grid(rows: dict[str, list[dict]], entries: Sequence[Entry], tasks: Sequence[str]) -> dict:
    """The benchmark as one grid's JSON twin (``experiments.aggregate``'s input): per task, every entry's cell
    under its key."""
    by_task = {s: {row["task"]: row for row in r} for s, r in rows.items()}
    return {"rows": [{"task": t, "methods": {e.key: by_task[e.student][t]["methods"][e.method] for e in entries}}
                     for t in tasks]}


# ---------------------------------------------------------------------------------------------- per task

def task_table(task: str, rows: dict[str, list[dict]], entries: Sequence[Entry],
               families: dict[str, dict]) -> list[dict]:
    """One row per entry on ``task``: its cell's statistics (``tables.table2_rows``) and its verdict against the
    student's baseline (None for the baseline itself and where it was not compared)."""
    judged = {(s, c["method"]): c for s, fam in families.items() for c in fam["comparisons"] if c["task"] == task}
    skipped = {(s, c["method"]): c["why"] for s, fam in families.items() for c in fam["skipped"] if c["task"] == task}
    out = []
    for e in entries:
        row = next(r for r in rows[e.student] if r["task"] == task)
        out.append({"student": e.student, "method": e.method, "label": e.label, "baseline": e.baseline,
                    **row["methods"][e.method], "verdict": judged.get((e.student, e.method)),
                    **({"not_compared": skipped[(e.student, e.method)]} if (e.student, e.method) in skipped else {})})
    return out


MATTERS_DEFINITION = (
    "exploration matters here: the spread between the best and the worst entry's mean final return on the task "
    "(every finished cell of the task at its most common budget, both students), over the seeds' standard deviation "
    "pooled over those cells (experiments.analysis.power.exploration_matters); and the spread as a fraction of the "
    "task's normalised range (reference − random policy's return) where the task has anchors. A task whose "
    "figure is small cannot tell strategies apart at any seed count")


def exploration_matters(per_task: dict[str, list[dict]], anchors: dict | None) -> list[dict]:
    """Per task of ``per_task`` (``task_table`` rows) with two finished cells at one budget: ``MATTERS_DEFINITION``'s
    figure, {"task", "budget", "cells", "best", "worst", "spread", "pooled_std", "figure", "spread_fraction"
    (None without anchors)}; entries are named by their keys (``<student>/<method>``)."""
    from experiments.analysis import power

    out = []
    for task, table in per_task.items():
        done = [r for r in table if r.get("status") == "done"]
        budgets = [r["budget"] for r in done]
        if not budgets:
            continue
        budget = max(set(budgets), key=lambda b: (budgets.count(b), b))  # the most common; ties: the longest
        finals = {f"{r['student']}/{r['method']}": r["per_seed"] for r in done if r["budget"] == budget}
        if len(finals) < 2 or all(len(v) < 2 for v in finals.values()):
            continue
        m = power.exploration_matters(finals)
        span = (anchors[task][1] - anchors[task][0]) if anchors and task in anchors else None
        out.append({"task": task, "budget": budget, "cells": len(finals), **m,
                    "spread_fraction": m["spread"] / span if span else None})
    return out


# ---------------------------------------------------------------------------------------------- aggregate

def best_fixed_noise(rep: dict, entries: Sequence[Entry]) -> dict[str, str]:
    """{student: the key of its best fixed noise}: the highest IQM point among the student's noise entries in the
    aggregate (``BEST_NOISE_RULE``; ties go to the earlier entry in ``STRATEGIES`` order)."""
    out = {}
    for student in dict.fromkeys(e.student for e in entries):
        noise = [e.key for e in entries if e.student == student and e.noise and e.key in rep["methods"]]
        if noise:
            out[student] = max(noise, key=lambda k: (rep["methods"][k]["IQM"]["point"], -noise.index(k)))
    return out


def improvement(scores: dict, entries: Sequence[Entry], present: Sequence[str], best: dict[str, str]) -> list[dict]:
    """The probability of improvement (``stats.probability_of_improvement``) of each entry of the aggregate over
    its student's baseline (reference "baseline"), then over its student's best fixed noise (``best_fixed_noise``)
    where that is not the baseline itself."""
    out = []
    for reference in ("baseline", "best fixed noise"):
        for e in entries:
            base = Entry(e.student, e.baseline).key
            y = base if reference == "baseline" else best.get(e.student)
            if e.key not in present or y not in present or y == e.key or (reference != "baseline" and y == base):
                continue
            point, lo, hi = stats.probability_of_improvement(scores[e.key], scores[y])
            out.append({"x": e.key, "y": y, "reference": reference, "point": point, "lo": lo, "hi": hi,
                        "per_task": stats.improvement_per_task(scores[e.key], scores[y])})
    return out


def aggregate_report(rows: dict[str, list[dict]], entries: Sequence[Entry], tasks: Sequence[str],
                     anchors: dict | None) -> tuple[dict | None, tuple | None, str | None]:
    """(report, scored, why not): ``experiments.aggregate``'s report of the benchmark over the tasks where every
    entry with a finished cell finished (``aggregate.grid_scores``), with this benchmark's probabilities of
    improvement (``improvement``), its best fixed noises and notes; (None, None, why) where it cannot be built."""
    from experiments import aggregate

    if anchors is None:
        return None, None, "no normalisation anchors (results/normalisation.json not found)"
    labels = {e.key: e.label for e in entries}
    grid = combined_grid(rows, entries, tasks)
    scored = aggregate.grid_scores(grid, anchors, labels)
    if not scored[1]:
        return None, None, "no entry has a finished cell"
    if not scored[0]:
        return None, None, "no task has a finished cell for every entry and normalisation anchors: " + "; ".join(
            scored[3])
    rep = aggregate.report(grid, anchors, scored, pairs=[])
    best = best_fixed_noise(rep, entries)
    rep["improvement"] = improvement(scored[2], entries, scored[1], best)
    rep["best_fixed_noise"] = {s: {"entry": k, "IQM": rep["methods"][k]["IQM"]["point"]} for s, k in best.items()}
    rep["best_fixed_noise_rule"] = BEST_NOISE_RULE
    rep["notes"] = [
        "scores are the seeds' final returns; every entry over the same tasks (those where every entry with a "
        "finished cell finished, and that have normalisation anchors); a `gym:` task has none and is left out.",
        "best fixed noise per student: " + "; ".join(
            f"{STUDENT_NAMES.get(s, s)}: {labels[k]} (IQM {stats.fmt(rep['methods'][k]['IQM']['point'], 2)})"
            for s, k in best.items()) + f". {BEST_NOISE_RULE[0].upper()}{BEST_NOISE_RULE[1:]}."]
    rep["labels"] = labels
    return rep, scored, None


# ---------------------------------------------------------------------------------------------- sample efficiency

def sample_efficiency(results: dict, entries: Sequence[Entry], tasks: Sequence[str], anchors: dict,
                      reps: int = stats.BOOTSTRAP_REPS) -> dict:
    """IQM of the normalised evaluation returns over training per entry (``CURVES_DEFINITION``), on the aggregate's
    ``tasks``, at the env steps where every cell of the aggregate was evaluated."""
    finished = lambda e, t: (e.student, t, e.method) in results and results[(e.student, t, e.method)].complete
    present = [e for e in entries if all(finished(e, t) for t in tasks)]
    common = None
    for e in present:
        for t in tasks:
            steps = set(int(s) for s in results[(e.student, t, e.method)].steps)
            common = steps if common is None else common & steps
    steps = sorted(common or ())
    out = {"definition": CURVES_DEFINITION.format(reps=reps, seed=stats.BOOTSTRAP_SEED), "tasks": list(tasks),
           "steps": steps, "entries": {}}
    for e in present:
        curve = {"label": e.label, "student": e.student, "method": e.method, "iqm": [], "lo": [], "hi": []}
        cells_ = [results[(e.student, t, e.method)] for t in tasks]
        for step in steps:
            per_task = [stats.normalise(r.values[:, int(np.flatnonzero(r.steps == step)[0])], *anchors[t])
                        for r, t in zip(cells_, tasks)]
            per_task = [x[np.isfinite(x)] for x in per_task]
            if any(x.size == 0 for x in per_task):
                point = lo = hi = None
            else:
                point, lo, hi = stats.aggregate_interval(per_task, stats.iqm, reps=reps)
            for k, v in (("iqm", point), ("lo", lo), ("hi", hi)):
                curve[k].append(v)
        out["entries"][e.key] = curve
    return out


# ---------------------------------------------------------------------------------------------- cost

def cost_rows(results: dict, entries: Sequence[Entry], tasks: Sequence[str]) -> list[dict]:
    """Per planned cell: its state and what it cost, from its records (none estimated): wall seconds of the
    recorded calls (reproduce.json, compile included), their CPU seconds (the process's user + system time, where
    recorded), training seconds of every call after compiling (the metrics rows, ``metric_rows.training_seconds``),
    the last call's compile seconds (summary.json), env steps per second (seeds x env steps / training seconds)
    and the machine's CPU count; for a finished cell of a paper task, what the same cell would take at the
    paper's budget (``paper_budget_projection``)."""
    from envs import default_budget, paper_tasks

    out = []
    for t in tasks:
        for e in entries:
            r = results.get((e.student, t, e.method))
            row = {"task": t, "student": e.student, "method": e.method, "label": e.label}
            if r is None:
                out.append({**row, "status": "not run"})
                continue
            prov = cells.cell_provenance(r)
            steps = r.num_seeds * r.env_steps_done
            train = r.train_seconds
            out.append({**row, "status": "done" if r.complete else "incomplete", "seeds": r.num_seeds,
                        "env_steps_done": r.env_steps_done, "budget": r.budget,
                        "wall_seconds": prov["wall_seconds"], "cpu_seconds": prov.get("cpu_seconds"),
                        "cpu_seconds_calls": prov.get("cpu_seconds_calls"),
                        "calls": len(r.provenance.get("calls") or []) or None,
                        "train_seconds": train, "compile_seconds": r.summary.get("compile_seconds"),
                        "env_steps_per_second": round(steps / train, 1) if train else None,
                        "cpu_count": (prov["machine"] or {}).get("cpu_count"), "physics": prov["physics"]})
            if r.complete and t in paper_tasks():
                out[-1].update(paper_budget_projection(out[-1], default_budget(t)))
    return out


def paper_budget_projection(row: dict, budget: int) -> dict:
    """What a finished cell would cost at ``budget`` env steps per seed, projected (not measured) from its own
    record: its compile seconds plus the rest of its wall time scaled by budget / its env steps; CPU seconds at
    its recorded CPU per wall second. Empty where the record lacks the wall time."""
    wall, done = row.get("wall_seconds"), row.get("env_steps_done")
    if not wall or not done:
        return {}
    compile_s = min(row.get("compile_seconds") or 0.0, wall)
    projected = compile_s + (wall - compile_s) * budget / done
    cpu = row.get("cpu_seconds")
    return {"paper_budget": budget, "paper_budget_wall_seconds": round(projected, 1),
            "paper_budget_cpu_seconds": round(cpu * projected / wall, 1) if cpu else None}


def cost_totals(rows: list[dict]) -> dict:
    """Sums over the stored cells (unfinished ones included: their calls ran), and which cells lack a record."""
    stored = [r for r in rows if r["status"] != "not run"]
    def total(key):  # None: no stored cell recorded it (e.g. CPU time, for cells run before it was recorded)
        values = [r[key] for r in stored if r.get(key) is not None]
        return round(sum(values), 2) if values else None

    calls = sum(r["calls"] or 0 for r in stored)
    return {"cells_stored": len(stored), "cells_done": sum(r["status"] == "done" for r in stored),
            "cells_not_run": len(rows) - len(stored),
            "wall_seconds": total("wall_seconds"), "cpu_seconds": total("cpu_seconds"),
            "train_seconds": total("train_seconds"),
            "paper_budget_wall_seconds": total("paper_budget_wall_seconds"),
            "paper_budget_cpu_seconds": total("paper_budget_cpu_seconds"),
            "calls_with_cpu_record": sum(r["cpu_seconds_calls"] or 0 for r in stored), "calls": calls,
            "cells_without_cpu_record": [f"{r['student']}/{r['task']}/{r['method']}" for r in stored
                                         if r.get("cpu_seconds") is None]}


# ---------------------------------------------------------------------------------------------- README, build


def verdict_counts(tables_: dict[str, list[dict]], entries: Sequence[Entry],
                   tasks: Sequence[str]) -> dict[str, dict[str, int]]:
    """{entry key: {verdict: number of tasks}} (``stats.VERDICTS``) of every entry but the baselines: its per-task
    verdicts against its student's baseline; a task where it was not compared (a cell not finished) is not
    counted."""
    out = {}
    for i, e in enumerate(entries):
        if e.method != e.baseline:
            said = [tables_[t][i]["verdict"]["verdict"] for t in tasks if tables_[t][i]["verdict"]]
            out[e.key] = {v: said.count(v) for v in stats.VERDICTS}
    return out


