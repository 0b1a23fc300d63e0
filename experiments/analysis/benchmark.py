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

import csv
import dataclasses
import json
import os
from typing import Sequence

import numpy as np

from experiments.analysis import cells, stats, tables
from experiments.grid.methods import (LEARNED, METHOD_NAMES, STRATEGIES, STUDENT_BASELINES, STUDENT_NAMES, noise_methods,
                                    task_folder, task_name)

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
    """The entries of ``students`` (``STRATEGIES`` order, then ``LEARNED``'s), restricted to ``strategies`` (grid
    methods) when given, else ``STRATEGIES``' only. Each student's baseline is always one of them (every other
    entry is judged against it): ``baselines[student]`` where given (a reference chosen in advance, e.g. the best
    fixed noise of an earlier benchmark), else its Gaussian noise. ``ValueError`` for a baseline that is not one of
    the student's strategies."""
    baselines = dict(baselines or {})
    for s, m in baselines.items():
        if s not in students:
            raise ValueError(f"baseline {s}={m}: {s!r} is not one of the planned students ({', '.join(students)})")
        if m not in (*STRATEGIES[s], *LEARNED.get(s, ())):
            raise ValueError(f"baseline {s}={m}: {m!r} is not a strategy of {s}; valid: "
                             + ", ".join((*STRATEGIES[s], *LEARNED.get(s, ()))))
    out = []
    for s in students:
        base = baselines.get(s, STUDENT_BASELINES[s])
        chosen = [m for m in STRATEGIES[s] if strategies is None or m in strategies or m == base]
        chosen += [m for m in LEARNED.get(s, ()) if strategies is not None and m in strategies or m == base]
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


def collect(runs_dir: str, results_dir: str, entries: Sequence[Entry], tasks: Sequence[str]) -> dict:
    """{(student, task, method): RunResult} of the stored cells, every finished run folder first (re)archived
    (``cells.archive_cell``); a cell without a finished run folder is read from the archive."""
    out = {}
    for student in dict.fromkeys(e.student for e in entries):
        methods = [e.method for e in entries if e.student == student]
        runs, results = student_dirs(runs_dir, results_dir, student)
        archive = cells.archive_dir_for(results, PRESET)
        for task in tasks:
            for method in methods:
                cells.archive_cell(os.path.join(runs, PRESET, task_folder(task), method),
                                   os.path.join(archive, task_folder(task), method), method, STUDENT_BASELINES[student])
        found = cells.collect(os.path.join(runs, PRESET), tasks, methods, archive_dir=archive)
        out.update({(student, t, m): r for (t, m), r in found.items()})
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


def _verdict_cells(r: dict) -> list[str]:
    if r["method"] == r["baseline"]:
        return ["baseline"] + ["–"] * 5
    v = r["verdict"]
    if v is None:
        why = r.get("not_compared") or ("not compared: a cell is not finished" if r["status"] == "done" else "–")
        return [why] + ["–"] * 5
    ci = "" if v["ci95"] is None else f" [{stats.fmt(v['ci95'][0])}, {stats.fmt(v['ci95'][1])}]"
    margin = "none" if v["margin"] is None else f"±{stats.fmt(v['margin'])}"
    return [f"{stats.fmt(v['difference'])}{ci}", margin, stats.fmt_p(v["p"]), stats.fmt_p(v["p_holm"]),
            stats.fmt_p(v["p_equivalence_holm"]), v["verdict"]]


def write_task_tables(task: str, table: list[dict], families: dict[str, dict], out_dir: str, footer: str,
                      build_commit: str | None) -> list[str]:
    """``tasks/<task>.md``, ``.json`` and ``_per_seed.csv``; returns the paths."""
    folder = os.path.join(out_dir, "tasks")
    os.makedirs(folder, exist_ok=True)
    base = os.path.join(folder, task_folder(task))
    paths = [base + ".md", base + ".json", base + "_per_seed.csv"]
    sizes = {s: len(f["comparisons"]) for s, f in families.items()}
    bases = {r["student"]: r["baseline"] for r in table}
    md = [f"# {task_name(task)}: final return of every student and strategy (exploration benchmark)", "",
          "Each row one cell (a student exploring with a strategy), its seeds' final returns; the verdict of each "
          "strategy against its student's baseline (" + ", ".join(
              f"{STUDENT_NAMES.get(s, s)}: {METHOD_NAMES.get(bases[s], bases[s])}"
              for s in families) + "), fixed in advance. \"not run\": no finished cell is stored (nothing is "
          "estimated). Raw per-seed numbers: `" + os.path.basename(paths[2]) + "`.", "",
          f"- {stats.FINAL_DEFINITION}.",
          "- mean ± std over seeds (ddof=1); 95% CI: mean ± t(0.975, n−1)·s/√n.",
          f"- {stats.VERDICT_DEFINITION}. Each student's family: every one of its strategies against its baseline "
          f"on every task of the benchmark (" + ", ".join(f"{STUDENT_NAMES.get(s, s)}: {n} comparisons"
                                                       for s, n in sizes.items()) + ").",
          "- a − b: difference of the mean final returns with its 95% Welch CI; margin: the equivalence margin in "
          "return units ('none': the task has no normalisation anchors, so it is never judged equivalent); p: raw "
          "Welch p; Holm p: corrected within the family; TOST p: the equivalence test's, Holm-corrected within the "
          "family.", "",
          "| student | strategy | final return | 95% CI | seeds | budget | a − b vs baseline [95% CI] | margin | p | "
          "Holm p | TOST p (Holm) | verdict |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in table:
        done = r["status"] == "done"
        seeds, budget = (str(r["n"]), f"{r['budget']:,}") if done else ("–", "–")
        md.append(f"| {STUDENT_NAMES.get(r['student'], r['student'])} | {r['label']} | {tables.cell_text(r)} | "
                  f"{tables.ci_text(r)} | {seeds} | {budget} | " + " | ".join(_verdict_cells(r)) + " |")
    md.append(footer)
    with open(paths[0], "w") as f:
        f.write("\n".join(md))
    with open(paths[1], "w") as f:
        json.dump({"task": task, "final_definition": stats.FINAL_DEFINITION,
                   "verdicts_definition": stats.VERDICT_DEFINITION,
                   "baselines": {s: bases[s] for s in families},
                   "family_sizes": sizes, "rows": table}, f, indent=2, default=tables.json_default)
    with open(paths[2], "w", newline="") as f:
        w = csv.writer(f)
        # seed_index i is the run's seed i: PRNG key fold_in(PRNGKey(base_seed), i).
        w.writerow(["task", "student", "method", "seed_index", "final_return", "final_evaluations", "evaluations",
                    "env_steps", "budget", "base_seed", "run_commit", "run_dir", "build_commit"])
        for r in table:
            if r["status"] != "done":
                continue
            for i, v in enumerate(r["per_seed"]):
                w.writerow([task, r["student"], r["method"], i, repr(v), r["final_evaluations"], r["evaluations"],
                            r["env_steps"], r["budget"], r["base_seed"], r["run_commit"] or "", r["run_dir"],
                            build_commit or ""])
    return paths


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


def plot_aggregate(rep: dict, entries: Sequence[Entry], path: str, build: dict) -> None:
    """IQM, mean and optimality gap per entry with their 95% stratified bootstrap intervals, grouped by student."""
    from experiments.analysis.figures import pyplot, save_figure

    plt = pyplot()
    shown = [e for e in entries if e.key in rep["methods"]]
    fig, axes = plt.subplots(1, 3, figsize=(12, 0.45 * len(shown) + 1.6), dpi=120, sharey=True)
    y = np.arange(len(shown))[::-1]
    for ax, name in zip(axes, ("IQM", "mean", "optimality gap")):
        for yi, e in zip(y, shown):
            v = rep["methods"][e.key][name]
            ax.plot([v["lo"], v["hi"]], [yi, yi], color=STUDENT_COLORS.get(e.student, "tab:gray"), lw=5, alpha=0.45,
                    solid_capstyle="butt")
            ax.plot([v["point"]], [yi], "|", color="k", ms=12)
        ax.set_title(name, fontsize=10)
        ax.grid(axis="x", alpha=0.3)
        ax.set_xlabel("normalised score")
    axes[0].set_yticks(y)
    axes[0].set_yticklabels([e.label for e in shown], fontsize=8)
    fig.suptitle(f"Exploration benchmark over {len(rep['tasks'])} task(s): 95% stratified bootstrap intervals",
                 fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, build)
    plt.close(fig)


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


def plot_sample_efficiency(curves: dict, path: str, build: dict) -> None:
    """One panel per student: each entry's IQM curve with its bootstrap band."""
    from experiments.analysis.figures import pyplot, save_figure

    plt = pyplot()
    students = list(dict.fromkeys(c["student"] for c in curves["entries"].values()))
    fig, axes = plt.subplots(1, max(1, len(students)), figsize=(6 * max(1, len(students)), 4.2), dpi=120,
                             squeeze=False, sharey=True)
    steps = np.asarray(curves["steps"], np.float64)
    for ax, student in zip(axes[0], students):
        for c in (c for c in curves["entries"].values() if c["student"] == student):
            f = lambda k: np.array([np.nan if v is None else v for v in c[k]], np.float64)
            line, = ax.plot(steps, f("iqm"), marker=".", label=c["label"])
            ax.fill_between(steps, f("lo"), f("hi"), color=line.get_color(), alpha=0.15)
        ax.set_title(STUDENT_NAMES.get(student, student), fontsize=10)
        ax.set_xlabel("environment steps")
        ax.set_ylabel("IQM normalised evaluation return")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"Sample efficiency over {', '.join(task_name(t) for t in curves['tasks'])} "
                 "(95% stratified bootstrap bands)", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, build)
    plt.close(fig)


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


def _hours(seconds: float | None) -> str:
    return "n/a" if seconds is None else f"{seconds / 3600:,.2f} h"


def _cpu_time(totals: dict) -> str:
    """'CPU time X h', 'CPU time X h (not recorded for N cells)' or 'CPU time not recorded'."""
    missing = len(totals["cells_without_cpu_record"])
    if totals["cpu_seconds"] is None:
        return "CPU time not recorded (cells run before their calls recorded it)"
    return f"CPU time {_hours(totals['cpu_seconds'])}" + (f" (not recorded for {missing} cells)" if missing else "")


def write_cost(rows: list[dict], totals: dict, out_dir: str, footer: str) -> list[str]:
    """``cost.md`` and ``cost.json``."""
    paths = [os.path.join(out_dir, "cost.md"), os.path.join(out_dir, "cost.json")]
    num = lambda v, f="{:,.0f}": "–" if v is None else f.format(v)
    md = ["# Cost of every cell (exploration benchmark)", "",
          f"Total over the {totals['cells_stored']} stored cells ({totals['cells_done']} finished; "
          f"{totals['cells_not_run']} not run): CPU time {_hours(totals['cpu_seconds'])} "
          f"({totals['calls_with_cpu_record']} of {totals['calls']} recorded calls measured it"
          + (f"; cells without a CPU record: {', '.join(totals['cells_without_cpu_record'])}"
             if totals["cells_without_cpu_record"] else "") + f"), wall time {_hours(totals['wall_seconds'])}, "
          f"training time {_hours(totals['train_seconds'])}.", "",
          "- wall s: the recorded calls of `experiments.benchmark` for the cell (`reproduce.json`: compile, training, "
          "evaluations, checkpoints); CPU s: their process CPU time (user + system, all threads); training s: every "
          "call's chunks after compiling (the metrics rows; also calls that a shutdown killed before they were "
          "recorded); compile s: the last call's compile (`summary.json`); env steps/s: seeds × env steps / "
          "training s; CPUs: the machine's core count. Nothing is estimated: a cell not run costs nothing here.",
          "- at the paper's budget: what the same finished cell would take at the paper's env steps per seed "
          "(`envs.default_budget`), projected from its own record, not measured: its compile seconds plus the rest "
          "of its wall time scaled by the budget over its env steps; CPU at its recorded CPU per wall second. "
          f"Over the finished cells: wall {_hours(totals.get('paper_budget_wall_seconds'))}, CPU "
          f"{_hours(totals.get('paper_budget_cpu_seconds'))}.", "",
          "| task | student | strategy | state | seeds | env steps | wall s | CPU s | training s | compile s | "
          "env steps/s | CPUs | paper budget | wall s at it (projected) | CPU s at it (projected) |",
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        state = (r["status"] if r["status"] != "incomplete" else
                 f"incomplete ({r['env_steps_done']:,} of {r['budget']:,})")
        md.append(f"| {task_name(r['task'])} | {STUDENT_NAMES.get(r['student'], r['student'])} | {r['label']} | "
                  f"{state} | "
                  f"{num(r.get('seeds'))} | {num(r.get('env_steps_done'))} | {num(r.get('wall_seconds'))} | "
                  f"{num(r.get('cpu_seconds'))} | {num(r.get('train_seconds'))} | "
                  f"{num(r.get('compile_seconds'), '{:,.1f}')} | {num(r.get('env_steps_per_second'))} | "
                  f"{num(r.get('cpu_count'))} | {num(r.get('paper_budget'))} | "
                  f"{num(r.get('paper_budget_wall_seconds'))} | {num(r.get('paper_budget_cpu_seconds'))} |")
    md.append(footer)
    with open(paths[0], "w") as f:
        f.write("\n".join(md))
    with open(paths[1], "w") as f:
        json.dump({"totals": totals, "cells": rows}, f, indent=2, default=tables.json_default)
    return paths


# ---------------------------------------------------------------------------------------------- README, build

FILES = {
    "README.md": "this page: the plan, the headline numbers, what each file holds",
    "manifest.json": "provenance: this build's commit and machine, the plan, and per cell its commits, dirty flag, "
                     "diffs, config, seeds, budget, machine, wall and CPU time",
    "aggregate.md": "aggregate over the tasks: IQM, mean and optimality gap of the normalised final returns per "
                    "student and strategy, and the probability of improvement over the student's baseline and "
                    "over its best fixed noise, with 95% stratified bootstrap intervals",
    "aggregate.json": "the same, machine-readable, with the anchors, the tasks left out and the best fixed noises",
    "aggregate_scores.png": "IQM, mean and optimality gap per student and strategy with their intervals",
    "performance_profiles.png": "performance profiles: the fraction of seeds above each normalised score",
    "sample_efficiency.json": "IQM of the normalised evaluation return at every common evaluation point, per "
                              "student and strategy, with bootstrap intervals",
    "sample_efficiency.png": "the same as curves with bands, one panel per student",
    "cost.md": "the cost of every cell: wall, CPU, training and compile seconds, env steps/s; the totals",
    "cost.json": "the same, machine-readable",
}


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

# Files of a results folder that no build writes, listed in its README when present.
KEPT_FILES = {
    "NOTES.md": "how the cells ran, kept by hand: their environment, cells that shared the CPU, records of more "
                "or fewer than one call",
    "packages.txt": "the Python environment the cells ran with (`pip freeze`)",
    "diagnostics.md": "the learned explorers' per-cycle diagnostics and the hypotheses' predictions (and with "
                      "`--goal` the judgement's goal), written by `python -m experiments.analysis.learned`",
    "diagnostics.json": "the same, machine-readable",
    "meta_reward.png": "the meta reward per cycle of every learned explorer's cell, drawn by the same command",
}


def _final_matrix(tables_: dict[str, list[dict]], entries: Sequence[Entry], tasks: Sequence[str],
                  counts: dict[str, dict[str, int]]) -> list[str]:
    """The README's final-return table; ``counts``: ``verdict_counts`` of the same tables."""
    cell = lambda r: (tables.cell_text(r) + ("" if r["method"] == r["baseline"] else
                                             f" ({r['verdict']['verdict']})" if r["verdict"] else ""))
    lines = ["| student | strategy | " + " | ".join(task_name(t) for t in tasks) + " | verdicts ("
             + " / ".join(stats.VERDICTS) + ") |", "|---|---|" + "---|" * (len(tasks) + 1)]
    for i, e in enumerate(entries):
        said = "baseline" if e.key not in counts else " / ".join(str(counts[e.key][v]) for v in stats.VERDICTS)
        lines.append(f"| {STUDENT_NAMES.get(e.student, e.student)} | {e.label} | "
                     + " | ".join(cell(tables_[t][i]) for t in tasks) + f" | {said} |")
    return lines


def _baselines_text(entries: Sequence[Entry]) -> str:
    """Each student's baseline, e.g. 'TD3 (normal noise), SAC (own policy)'."""
    return ", ".join(Entry(s, m).label for s, m in baselines_of(entries).items())


def write_readme(out_dir: str, manifest: dict, tables_: dict, entries: Sequence[Entry], tasks: Sequence[str],
                 rep: dict | None, totals: dict, footer: str) -> str:
    plan = manifest["benchmark"]
    labels = {e.key: e.label for e in entries}
    interval = lambda v: f"{stats.fmt(v['point'], 2)} [{stats.fmt(v['lo'], 2)}, {stats.fmt(v['hi'], 2)}]"
    done = sum(c["complete"] for c in manifest["cells"])
    budget = "each task's paper budget" if plan.get("steps") is None else f"{plan['steps']:,} env steps per seed"
    lines = [f"# Exploration benchmark `{plan['name']}`: which exploration for an off-policy learner, and by how "
             "much does it matter?", "",
             f"Every student ({', '.join(STUDENT_NAMES.get(s, s) for s in plan['students'])}) with each of its "
             f"strategies on {len(tasks)} task(s), {plan['seeds']} seeds per cell from base seed {plan['seed']}, "
             f"{budget}, {plan.get('physics')} physics for the MuJoCo tasks; the paper preset's networks and schedule "
             "(the tuned teacher: the tuned preset). Made by `python -m experiments.benchmark` "
             f"(`{' '.join(plan.get('argv') or []) or 'default options'}`), which runs, resumes and skips cells and "
             f"rebuilds this folder from the stored ones (`--artefacts-only`: rebuild only). {done} of "
             f"{len(entries) * len(tasks)} cells are finished; {len(manifest['not_run'])} not run"
             + (f" ({', '.join('/'.join(c) for c in manifest['not_run'])})" if 0 < len(manifest["not_run"]) <= 12
                else " (listed in `manifest.json`)" if manifest["not_run"] else "") + ".", "",
             "| file | content |", "|---|---|"]
    for f in manifest["files"]:
        if f.startswith("tasks/") and f.endswith(".md"):
            lines.append(f"| `{f}` | per task: every cell's final return (mean ± std, 95% CI, seeds, budget) and its "
                         f"corrected verdict against the student's baseline |")
        elif f.startswith("tasks/") and f.endswith("_per_seed.csv"):
            lines.append(f"| `{f}` | the raw per-seed final returns of that task's finished cells |")
        elif f.startswith("tasks/"):
            lines.append(f"| `{f}` | the same as the task's table, machine-readable |")
        elif f in FILES:
            lines.append(f"| `{f}` | {FILES[f]} |")
    lines += [f"| `{f}` | {text} |" for f, text in KEPT_FILES.items() if os.path.exists(os.path.join(out_dir, f))]
    lines.append("| `<student>/cells/<task>/<method>/` | the archived cells: config, metrics, summary, "
                 "`reproduce.json` (commands, commits, wall and CPU time), diffs of uncommitted changes |")
    lines += ["", "## Final return per task", "",
              f"Mean ± std of the seeds' final returns ({stats.FINAL_DEFINITION}); in brackets the verdict against "
              "the student's baseline (" + _baselines_text(entries) + "; Holm-corrected within the student's family; "
              "details per task in `tasks/`); in the last column the number of tasks with each verdict.",
              ""] + _final_matrix(tables_, entries, tasks, manifest["verdict_counts"])
    lines += ["", "## Aggregate over tasks", ""]
    if rep is None:
        lines.append(f"Not built: {manifest['aggregate_not_built']}.")
    else:
        anchors = rep.get("built", {}).get("anchors", "results/normalisation.json")
        lines += [f"Over {', '.join(task_name(t) for t in rep['tasks'])}"
                  + (f"; left out: {'; '.join(rep['left_out'])}" if rep["left_out"] else "")
                  + f". Normalised final returns (0 = a uniformly random policy, 1 = Table 2's DDPG with parameter "
                  f"noise at the paper's budget; `{anchors}`); 95% stratified bootstrap intervals (`aggregate.md`).",
                  "", "| student | strategy | IQM | mean | optimality gap |", "|---|---|---|---|---|"]
        for e in entries:
            if e.key in rep["methods"]:
                m = rep["methods"][e.key]
                lines.append(f"| {STUDENT_NAMES.get(e.student, e.student)} | {e.label} | {interval(m['IQM'])} | "
                             f"{interval(m['mean'])} | {interval(m['optimality gap'])} |")
        lines += ["", f"Probability of improvement P(X > Y): the chance that a seed of X ends above a seed of Y on a "
                  f"task drawn from these tasks. Baselines: {_baselines_text(entries)}. "
                  f"{BEST_NOISE_RULE[0].upper()}{BEST_NOISE_RULE[1:]}.", "",
                  "| X | over its baseline | over its best fixed noise (which) |", "|---|---|---|"]
        by = {(p["x"], p["reference"]): p for p in rep["improvement"]}
        for e in entries:
            if e.key not in rep["methods"]:
                continue
            g, b = by.get((e.key, "baseline")), by.get((e.key, "best fixed noise"))
            best = rep["best_fixed_noise"].get(e.student, {}).get("entry")
            lines.append(f"| {e.label} | {interval(g) if g else '–'} | "
                         + (f"{interval(b)} ({labels.get(best, best)})" if b else
                            "– (it is the best)" if best == e.key else
                            "(its baseline is the best)" if best == Entry(e.student, e.baseline).key else "–") + " |")
    lines += ["", "## Cost", "",
              f"{totals['cells_stored']} stored cells: {_cpu_time(totals)}, wall time "
              f"{_hours(totals['wall_seconds'])}; per cell in `cost.md`, with what each finished cell would take at "
              f"the paper's budget (projected from its own record, not measured; over the finished cells: wall "
              f"{_hours(totals.get('paper_budget_wall_seconds'))}, CPU "
              f"{_hours(totals.get('paper_budget_cpu_seconds'))})."]
    lines.append(footer)
    path = os.path.join(out_dir, "README.md")
    with open(path, "w") as f:
        f.write("\n".join(lines))
    return path


def build(runs_dir: str, results_dir: str, entries: Sequence[Entry], tasks: Sequence[str],
          plan: dict | None = None, anchors_path: str | None = None, extra_provenance: dict | None = None) -> dict:
    """Rebuilds ``results_dir`` from the stored cells of ``entries`` x ``tasks`` (``collect``); returns the manifest.

    ``plan``: the benchmark's options (name, students, strategies, seeds, seed, steps, physics, argv), written into
    the README and the manifest; ``anchors_path`` (default ``results/normalisation.json``): the normalisation
    anchors of the aggregate and of the verdicts' equivalence margins."""
    from experiments import aggregate, normalisation

    os.makedirs(results_dir, exist_ok=True)
    anchors_path = normalisation.DEFAULT_OUT if anchors_path is None else anchors_path
    anchors = normalisation.load(anchors_path) if os.path.exists(anchors_path) else None
    results = collect(runs_dir, results_dir, entries, tasks)
    build_ = cells.build_info(runs_dir)
    build_.update(extra_provenance or {})
    footer = cells.provenance_footer(build_, results.values())
    rows = student_rows(results, entries, tasks)
    families = verdicts(rows, entries, anchors)
    files, per_task = [], {}
    for t in tasks:
        per_task[t] = task_table(t, rows, entries, families)
        files += write_task_tables(t, per_task[t], families, results_dir, footer, build_["commit"])
    rep, scored, why = aggregate_report(rows, entries, tasks, anchors)
    stale = ["aggregate.md", "aggregate.json", "performance_profiles.png", "aggregate_scores.png",
             "sample_efficiency.json", "sample_efficiency.png"]
    for name in stale:  # only what this build writes stays
        if os.path.exists(os.path.join(results_dir, name)):
            os.remove(os.path.join(results_dir, name))
    if rep is not None:
        labels = rep.pop("labels")
        files += aggregate.write(rep, scored, results_dir, "Exploration benchmark", {
            "date": build_["built"][:10], "commit": build_["commit"], "dirty": build_["dirty"],
            "grid": "tasks/*.json", "anchors": aggregate.repo_path(anchors_path)}, labels=labels)
        path = os.path.join(results_dir, "aggregate_scores.png")
        plot_aggregate(rep, entries, path, build_)
        curves = sample_efficiency(results, entries, rep["tasks"], anchors)
        with open(os.path.join(results_dir, "sample_efficiency.json"), "w") as f:
            json.dump(curves, f, indent=2, default=tables.json_default)
        files += [path, os.path.join(results_dir, "sample_efficiency.json")]
        if curves["steps"] and curves["entries"]:
            plot_sample_efficiency(curves, os.path.join(results_dir, "sample_efficiency.png"), build_)
            files.append(os.path.join(results_dir, "sample_efficiency.png"))
    costs = cost_rows(results, entries, tasks)
    totals = cost_totals(costs)
    files += write_cost(costs, totals, results_dir, footer)
    manifest = {
        "build": build_, "benchmark": {**(plan or {}), "tasks": list(tasks),
                                       "entries": [dataclasses.asdict(e) for e in entries],
                                       "baselines": baselines_of(entries)},
        "files": [os.path.relpath(p, results_dir) for p in files] + ["README.md", "manifest.json"],
        "cells": [{**cells.cell_provenance(r), "student": s} for (s, _, _), r in results.items()],
        "not_run": [[e.student, t, e.method] for t in tasks for e in entries
                    if (e.student, t, e.method) not in results],
        "unfinished": [[e.student, t, e.method] for t in tasks for e in entries
                       if (e.student, t, e.method) in results and not results[(e.student, t, e.method)].complete],
        "cost": totals, "verdict_counts": verdict_counts(per_task, entries, tasks),
        **({"aggregate": {"tasks": rep["tasks"], "left_out": rep["left_out"],
                          "best_fixed_noise": rep["best_fixed_noise"]}} if rep else {"aggregate_not_built": why})}
    write_readme(results_dir, manifest, per_task, entries, tasks, rep, totals, footer)
    with open(os.path.join(results_dir, "manifest.json"), "w") as f:
        json.dump(manifest, f, indent=2, default=tables.json_default)
    return manifest
