"""The exploration benchmark's files (``experiments.benchmark``): per-task tables, the aggregate's and the
sample-efficiency figures, the cost table, ``README.md`` and ``manifest.json``, and ``build``, which computes
them from the stored cells (``experiments.analysis.benchmark``) and writes them."""

from __future__ import annotations

import csv
import dataclasses
import json
import os
from typing import Sequence

import numpy as np

from experiments.analysis import cells, stats
from experiments.analysis.render import tables as tables_md
from experiments.analysis.benchmark import (BEST_NOISE_RULE, PRESET, STUDENT_COLORS, Entry,
                                            aggregate_report, baselines_of, collect, cost_rows, cost_totals,
                                            exploration_matters, sample_efficiency, student_rows, task_table,
                                            verdict_counts, verdicts)
from experiments.analysis.render.matters import write_matters
from experiments.grid.methods import METHOD_NAMES, STUDENT_NAMES, task_folder, task_name


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
                      build_commit: str | None, anchors: str = "results/normalisation.json") -> list[str]:
    """``tasks/<task>.md``, ``.json`` and ``_per_seed.csv``; returns the paths. ``anchors``: the anchors file the
    verdicts' definition names."""
    definition = stats.VERDICT_DEFINITION.replace("results/normalisation.json", anchors)
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
          f"- {definition}. Each student's family: every one of its strategies against its baseline "
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
        md.append(f"| {STUDENT_NAMES.get(r['student'], r['student'])} | {r['label']} | {tables_md.cell_text(r)} | "
                  f"{tables_md.ci_text(r)} | {seeds} | {budget} | " + " | ".join(_verdict_cells(r)) + " |")
    md.append(footer)
    with open(paths[0], "w") as f:
        f.write("\n".join(md))
    with open(paths[1], "w") as f:
        json.dump({"task": task, "final_definition": stats.FINAL_DEFINITION,
                   "verdicts_definition": definition,
                   "baselines": {s: bases[s] for s in families},
                   "family_sizes": sizes, "rows": table}, f, indent=2, default=tables_md.json_default)
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


def plot_aggregate(rep: dict, entries: Sequence[Entry], path: str, build: dict) -> None:
    """IQM, mean and optimality gap per entry with their 95% stratified bootstrap intervals, grouped by student."""
    from experiments.analysis.render.figures import pyplot, save_figure

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


def plot_sample_efficiency(curves: dict, path: str, build: dict) -> None:
    """One panel per student: each entry's IQM curve with its bootstrap band."""
    from experiments.analysis.render.figures import pyplot, save_figure

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
        json.dump({"totals": totals, "cells": rows}, f, indent=2, default=tables_md.json_default)
    return paths


def _final_matrix(tables_: dict[str, list[dict]], entries: Sequence[Entry], tasks: Sequence[str],
                  counts: dict[str, dict[str, int]]) -> list[str]:
    """The README's final-return table; ``counts``: ``verdict_counts`` of the same tables."""
    cell = lambda r: (tables_md.cell_text(r) + ("" if r["method"] == r["baseline"] else
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
                 rep: dict | None, totals: dict, footer: str, reference: str = "") -> str:  # reference: a score of 1
    plan = manifest["benchmark"]
    labels = {e.key: e.label for e in entries}
    interval = lambda v: f"{stats.fmt(v['point'], 2)} [{stats.fmt(v['lo'], 2)}, {stats.fmt(v['hi'], 2)}]"
    done = sum(c["complete"] for c in manifest["cells"])
    budget = "each task's paper budget" if plan.get("steps") is None else f"{plan['steps']:,} env steps per seed"
    own = plan.get("task_settings") or {}  # the tasks with a budget, seed count or overrides of their own
    budget += "".join(f" ({task_name(t)}: {d['seeds']} seeds, {d['steps']:,} env steps per seed"
                      + "".join(f", `{x}`" for x in d["overrides"]) + ")" for t, d in own.items())
    lines = [f"# Exploration benchmark `{plan['name']}`: which exploration for an off-policy learner, and by how "
             "much does it matter?", "",
             f"Every student ({', '.join(STUDENT_NAMES.get(s, s) for s in plan['students'])}) with each of its "
             f"strategies on {len(tasks)} task(s), {plan['seeds']} seeds per cell from base seed {plan['seed']}, "
             f"{budget}, {plan.get('physics')} physics for the MuJoCo tasks; the {plan.get('preset', 'paper')} preset's "
             "networks and schedule "
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
                  + f". Normalised final returns (0 = a uniformly random policy, 1 = {reference}; `{anchors}`); 95% "
                  "stratified bootstrap intervals (`aggregate.md`).",
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
          plan: dict | None = None, anchors_path: str | None = None, extra_provenance: dict | None = None,
          preset: str = PRESET) -> dict:
    """Rebuilds ``results_dir`` from the stored cells of ``entries`` x ``tasks`` (``collect``); returns the manifest.

    ``plan``: the benchmark's options (name, students, strategies, seeds, seed, steps, physics, argv), written into
    the README and the manifest; ``anchors_path`` (default ``results/normalisation.json``): the normalisation
    anchors of the aggregate and of the verdicts' equivalence margins; ``preset``: the grid's (its cells'
    folders)."""
    from experiments import aggregate, normalisation

    os.makedirs(results_dir, exist_ok=True)
    anchors_path = normalisation.DEFAULT_OUT if anchors_path is None else anchors_path
    anchors = normalisation.load(anchors_path) if os.path.exists(anchors_path) else None
    results = collect(runs_dir, results_dir, entries, tasks, preset)
    build_ = cells.build_info(runs_dir)
    build_.update(extra_provenance or {})
    footer = cells.provenance_footer(build_, results.values())
    rows = student_rows(results, entries, tasks)
    families = verdicts(rows, entries, anchors)
    files, per_task = [], {}
    for t in tasks:
        per_task[t] = task_table(t, rows, entries, families)
        files += write_task_tables(t, per_task[t], families, results_dir, footer, build_["commit"],
                                   aggregate.repo_path(anchors_path))
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
            json.dump(curves, f, indent=2, default=tables_md.json_default)
        files += [path, os.path.join(results_dir, "sample_efficiency.json")]
        if curves["steps"] and curves["entries"]:
            plot_sample_efficiency(curves, os.path.join(results_dir, "sample_efficiency.png"), build_)
            files.append(os.path.join(results_dir, "sample_efficiency.png"))
    costs = cost_rows(results, entries, tasks)
    totals = cost_totals(costs)
    files += write_cost(costs, totals, results_dir, footer)
    files += write_matters(exploration_matters(per_task, anchors), results_dir, footer)
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
    write_readme(results_dir, manifest, per_task, entries, tasks, rep, totals, footer,
                 normalisation.describe_reference(anchors_path, rep["tasks"], task_name) if rep else "")
    with open(os.path.join(results_dir, "manifest.json"), "w") as f:
        json.dump(manifest, f, indent=2, default=tables_md.json_default)
    return manifest


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
    "exploration_matters.md": "per task: its best and worst entries' spread over the seeds' std, and over its range",
    "exploration_matters.json": "the same, machine-readable",
}


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
