"""Table 2's files (``experiments.artefacts``): ``table2.md``/``.json``, steps-to-threshold and the comparisons, each
as markdown and JSON, and the texts of a table's cells, from what ``experiments.analysis.tables`` computes."""

from __future__ import annotations

import csv
import json
import os
from typing import Iterable, Sequence

import numpy as np

from experiments.analysis.cells import RunResult
from experiments.analysis.stats import (FINAL_DEFINITION, VERDICT_DEFINITION, fmt, fmt_p,
                                        stats_definition)
from experiments.analysis.tables import PAPER_SEEDS, paper_table2, verdict_families
from experiments.grid.methods import METHOD_NAMES, STUDENT_NAMES, baseline_for, grid_label, task_name


def write_md_and_json(md_path: str, md: list[str], json_path: str, preset: str, student: str, payload: dict) -> None:
    """An artefact's Markdown lines and its JSON twin, which opens with the grid (preset; student if not DDPG)."""
    with open(md_path, "w") as f:
        f.write("\n".join(md))
    with open(json_path, "w") as f:
        json.dump({"preset": preset, **({} if student == "ddpg" else {"student": student}), **payload}, f,
                  indent=2, default=json_default)


def verdicts_markdown(families: list[dict]) -> list[str]:
    """The verdict tables of ``verdict_families``, one per baseline."""
    name = lambda m: METHOD_NAMES.get(m, m)
    md = ["## Verdicts against each noise baseline (corrected for the number of comparisons)", "",
          f"- {VERDICT_DEFINITION}.",
          "- a − b: difference of the mean final returns, with its 95% Welch CI (t(0.975, Welch-Satterthwaite "
          "df)); margin: the equivalence margin in return units; p: raw Welch p; Holm p: corrected over the "
          "family; TOST p: the equivalence test's p, Holm-corrected over the family."]
    for fam in families:
        n = len(fam["comparisons"])
        md += ["", f"### Against {name(fam['baseline'])}"
               + (" (the grid's baseline, fixed in advance)" if fam["fixed_in_advance"] else "")
               + f": a family of {n} comparison{'s' if n != 1 else ''}", ""]
        if not n:
            md.append("No teacher and this baseline both finished on a task at the same budget: nothing is compared.")
        else:
            md += ["| task | method | a − b | 95% CI | margin | p | Holm p | TOST p (Holm) | verdict |",
                   "|---|---|---|---|---|---|---|---|---|"]
            for c in fam["comparisons"]:
                ci = "n/a" if c["ci95"] is None else f"[{fmt(c['ci95'][0])}, {fmt(c['ci95'][1])}]"
                md.append(f"| {task_name(c['task'])} | {name(c['method'])} | {fmt(c['difference'])} | {ci} | "
                          f"{'n/a' if c['margin'] is None else '±' + fmt(c['margin'])} | {fmt_p(c['p'])} | "
                          f"{fmt_p(c['p_holm'])} | {fmt_p(c['p_equivalence_holm'])} | {c['verdict']} |")
        for s in fam["skipped"]:
            md += ["", f"{task_name(s['task'])}, {name(s['method'])}: not compared ({s['why']})."]
    return md


def cell_text(cell: dict) -> str:
    if cell["status"] == "not run":
        return "not run"
    if cell["status"] == "incomplete":
        return f"incomplete ({cell['env_steps_done']:,} of {cell['budget']:,} steps)"
    return f"{fmt(cell['mean'])} ± {fmt(cell['std'])}"


def ci_text(cell: dict) -> str:
    """A cell's 95% CI column: '[lo, hi] (n=N)', or 'not run' / 'incomplete'."""
    if cell["status"] != "done":
        return cell["status"] if cell["status"] == "not run" else "incomplete"
    if cell["ci95"] is None:
        return f"{fmt(cell['mean'])} (n={cell['n']}, no CI)"
    lo, hi = cell["ci95"]
    return f"[{fmt(lo)}, {fmt(hi)}] (n={cell['n']})"


def _joined(values: dict) -> str:
    """One value, or 'method: value' pairs when the methods differ."""
    distinct = sorted(set(values.values()))
    if not distinct:
        return "—"
    if len(distinct) == 1:
        return f"{distinct[0]:,}"
    return "; ".join(f"{METHOD_NAMES.get(m, m)}: {v:,}" for m, v in values.items())


def budget_text(task: str, budgets: dict) -> str:
    """The budget column: ``_joined`` budgets, flagged when a cell ran fewer steps than the paper's budget
    (``envs.default_budget``: the paper's, rounded down to whole evaluation intervals), so that a
    reduced-budget row is never read against the paper's full-budget numbers unmarked."""
    from envs import default_budget, get_spec  # brax on import: only when a table is written

    text = _joined(budgets)
    if paper_table2(task) is not None and budgets and min(budgets.values()) < default_budget(task):
        text += f" (reduced; paper: {get_spec(task).paper_budget:,})"
    return text


def engines_text(results: Iterable[RunResult]) -> str:
    """How the stored MuJoCo cells were stepped: 'MJX', "MuJoCo's C engine" or both (a JAX task has neither), and
    what a grid with no MuJoCo cell stored has: the JAX tasks of its cells only."""
    import envs  # brax on import: only when a table is written

    results = list(results)
    physics = {r.config["env"].get("physics", "mjx") for r in results if envs.has_mujoco(r.task)}
    names = {"mjx": "MJX", "mujoco": "MuJoCo's C engine"}
    if physics:
        return " and ".join(names[p] for p in sorted(physics))
    stored = {r.task for r in results}
    return f"JAX ({', '.join(task_name(t) for t in envs.TASKS if t in stored)} only: no MuJoCo cell stored)"


def write_table2(rows: list[dict], methods: Sequence[str], out_dir: str, footer: str, preset: str,
                 build_commit: str | None = None, engines: str = "MJX", student: str = "ddpg",
                 families: list[dict] | None = None) -> list[str]:
    """table2.md, table2.json and table2_per_seed.csv from ``table2_rows`` and ``verdict_families`` (computed
    without anchors when not given); returns the paths."""
    os.makedirs(out_dir, exist_ok=True)
    names = [METHOD_NAMES.get(m, m) for m in methods]
    baseline = baseline_for(preset, student)
    families = verdict_families(rows, methods, baseline) if families is None else families
    protocol = ("" if preset == "paper" and student == "ddpg" else
                f" The paper's numbers are for its own protocol ({'' if student == 'ddpg' else 'DDPG with '}the "
                f"paper preset's networks, noise and budgets), not for the {grid_label(preset, student)}: they are "
                f"there for scale only.")
    md = [f"# Table 2: final evaluation return ({grid_label(preset, student)})", "",
          f"Rows: tasks; columns: methods, mean ± std over the seeds run here, next to the paper's Table 2 "
          f"(Meta / DDPG; {PAPER_SEEDS} seeds, gym v1 tasks, so not directly comparable: our tasks are gymnasium "
          f"v5 models on {engines}). \"not run\": no finished run is stored for that cell (nothing is estimated); "
          f"\"reduced\" in the budget column: fewer env steps per seed than the paper's budget."
          + protocol, "",
          f"- {FINAL_DEFINITION}.", f"- {stats_definition(baseline)}.", "",
          "| task | " + " | ".join(names) + " | paper Meta | paper DDPG | budget (env steps / seed) | seeds run |",
          "|---|" + "---|" * len(names) + "---|---|---|---|"]
    for row in rows:
        cells = [cell_text(row["methods"][m]) for m in methods]
        paper = row["paper"]
        pm = f"{paper['meta'][0]:,g} ± {paper['meta'][1]:,g}" if paper else "—"  # as printed in the paper
        pd = f"{paper['ddpg'][0]:,g} ± {paper['ddpg'][1]:,g}" if paper else "—"
        done = {m: c for m, c in row["methods"].items() if c["status"] == "done"}
        budget = budget_text(row["task"], {m: c["budget"] for m, c in done.items()})
        seeds = _joined({m: c["n"] for m, c in done.items()})
        md.append(f"| {task_name(row['task'])} | " + " | ".join(cells) +
                  f" | {pm} | {pd} | {budget} | {seeds} |")
    md += ["", "## 95% confidence intervals", "", "| task | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    for row in rows:
        md.append(f"| {task_name(row['task'])} | " +
                  " | ".join(ci_text(row["methods"][m]) for m in methods) + " |")
    md += [""] + verdicts_markdown(families)
    md.append(footer)
    paths = [os.path.join(out_dir, n) for n in ("table2.md", "table2.json", "table2_per_seed.csv")]
    write_md_and_json(paths[0], md, paths[1], preset, student,
                       {"baseline": baseline, "final_definition": FINAL_DEFINITION,
                        "statistics": stats_definition(baseline), "verdicts_definition": VERDICT_DEFINITION,
                        "paper_seeds": PAPER_SEEDS, "rows": rows, "verdicts": families})
    with open(paths[2], "w", newline="") as f:
        w = csv.writer(f)
        # seed_index i is the run's seed i: PRNG key fold_in(PRNGKey(base_seed), i).
        w.writerow(["task", "method", "seed_index", "final_return", "final_evaluations", "evaluations",
                    "env_steps", "budget", "base_seed", "run_commit", "backend", "run_wall_seconds", "run_dir",
                    "build_commit"])
        for row in rows:
            for m in methods:
                c = row["methods"][m]
                if c["status"] != "done":
                    continue
                for i, v in enumerate(c["per_seed"]):
                    w.writerow([row["task"], m, i, repr(v), c["final_evaluations"], c["evaluations"],
                                c["env_steps"], c["budget"], c["base_seed"], c["run_commit"] or "", c["backend"] or "",
                                "" if c["wall_seconds"] is None else c["wall_seconds"], c["run_dir"],
                                build_commit or ""])
    return paths


def json_default(x):
    """``json.dump``'s ``default``: NumPy scalars and arrays as Python values."""
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(type(x))


def write_steps_to_threshold(rows: list[dict], out_dir: str, footer: str, preset: str,
                             build_commit: str | None = None, student: str = "ddpg") -> list[str]:
    paths = [os.path.join(out_dir, "steps_to_threshold.csv"), os.path.join(out_dir, "steps_to_threshold.md")]
    keys = ["task", "method", "threshold", "baseline_step", "step", "ratio", "seeds", "env_steps_run", "complete",
            "baseline_complete"]
    with open(paths[0], "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys + ["build_commit"])
        w.writeheader()
        for row in rows:
            w.writerow({**{k: ("" if row[k] is None else row[k]) for k in keys}, "build_commit": build_commit or ""})
    baseline = METHOD_NAMES.get(baseline_for(preset, student), baseline_for(preset, student))
    md = [f"# Samples to reach the {STUDENT_NAMES.get(student, student)} baseline's best ({grid_label(preset, student)})", "",
          f"Threshold: the best value over evaluations of the {baseline} seed-mean evaluation-return curve. "
          "`step`: the first evaluation's env step at which a method's seed-mean curve reaches it; "
          f"`ratio` = step / {STUDENT_NAMES.get(student, student)}'s own step (the paper: Meta needs about 1/6 of "
          "DDPG's samples on InvertedDoublePendulum). \"not reached\": never within the env steps run.", "",
          f"| task | method | threshold | step | {STUDENT_NAMES.get(student, student)} step | ratio | env steps run "
          "| seeds |",
          "|---|---|---|---|---|---|---|---|"]
    for row in rows:
        step = "not reached" if row["step"] is None else f"{row['step']:,}"
        bstep = "n/a" if row["baseline_step"] is None else f"{row['baseline_step']:,}"
        run = f"{row['env_steps_run']:,}" + ("" if row["complete"] else " (incomplete)")
        ratio = "n/a" if row["ratio"] is None else f"{row['ratio']:.3f}"
        md.append(f"| {task_name(row['task'])} | {METHOD_NAMES.get(row['method'], row['method'])} "
                  f"| {fmt(row['threshold'])} | {step} | {bstep} | {ratio} | {run} | {row['seeds']} |")
    if not rows:
        md.append(f"| (no task has a {baseline} run) | | | | | | | |")
    md.append(footer)
    with open(paths[1], "w") as f:
        f.write("\n".join(md))
    return paths


def write_comparisons(comparisons: dict, out_dir: str, footer: str, preset: str,
                      build_commit: str | None = None, student: str = "ddpg") -> list[str]:
    """comparisons.md and comparisons.json from ``comparison_rows``; returns the paths."""
    paths = [os.path.join(out_dir, "comparisons.md"), os.path.join(out_dir, "comparisons.json")]
    name = lambda m: METHOD_NAMES.get(m, m)
    md = [f"# Every method against every other ({grid_label(preset, student)})", "",
          "The numbers docs/results.md quotes beyond `table2.md`, all from the same stored cells (finished "
          "cells only; pairs only between cells of the same budget).", "",
          f"- {FINAL_DEFINITION}.",
          "- best seed mean: the highest value of the seed-mean evaluation curve, and the env step of that "
          "evaluation; mean over evaluations: the seed-mean curve averaged over all its evaluations.",
          "- a − b: difference of the mean final returns; p: two-sided Welch t-test of the seeds' final returns; "
          "a above b (b above a): at how many of the evaluation steps both cells have the seed-mean curve of a "
          "is strictly above b's (b's above a's)."]
    for task in dict.fromkeys(r["task"] for r in comparisons["methods"]):
        md += ["", f"## {task_name(task)}", "",
               "| method | seeds | budget | mean final | median | min | max | best seed mean (step) | "
               "mean over evaluations |", "|---|---|---|---|---|---|---|---|---|"]
        for r in (r for r in comparisons["methods"] if r["task"] == task):
            md.append(f"| {name(r['method'])} | {r['n']} | {r['budget']:,} | {fmt(r['mean'])} | {fmt(r['median'])} "
                      f"| {fmt(r['min'])} | {fmt(r['max'])} | {fmt(r['best_seed_mean'])} "
                      f"({r['best_seed_mean_step']:,}) | {fmt(r['mean_over_evaluations'])} |")
        pairs = [p for p in comparisons["pairs"] if p["task"] == task]
        if pairs:
            md += ["", "| a | b | a − b | Welch t | p | a above b | b above a |", "|---|---|---|---|---|---|---|"]
            for p in pairs:
                md.append(f"| {name(p['a'])} | {name(p['b'])} | {fmt(p['difference'])} | {fmt(p['t'], 2)} | "
                          f"{fmt_p(p['p'])} | {p['a_above_b']} of {p['common_evaluations']} | "
                          f"{p['b_above_a']} of {p['common_evaluations']} |")
    if not comparisons["methods"]:
        md += ["", "(no finished cell is stored)"]
    md.append(footer)
    write_md_and_json(paths[0], md, paths[1], preset, student,
                       {"final_definition": FINAL_DEFINITION, "build_commit": build_commit, **comparisons})
    return paths
