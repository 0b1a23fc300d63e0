"""A screen of teacher variants: Algorithm 1's knobs changed one at a time from the paper preset, next to
the paper's teacher and both DDPG noise baselines, at a reduced budget, on the tasks where the paper's
teacher loses (Hopper and HalfCheetah).

    python -m experiments.screen                                   # Hopper then HalfCheetah, 300k, 8 seeds
    python -m experiments.screen --tasks hopper --variants paper-teacher,normalised-reward
    python -m experiments.screen --report-only                     # rebuild results/screen/ from what is stored

Every cell is an ``experiments.reproduce`` cell (same planning, resume, ``reproduce.json`` provenance and
archive; ``plan_cell`` with the variant's run options): ``<runs-dir>/paper/<task>/<variant>``, archived to
``<results-dir>/cells/<task>/<variant>``. Run the same command again to resume. The report
(``<results-dir>/README.md``, and per task ``<results-dir>/<task>/`` from ``experiments.ablation``: table,
``per_seed.csv``, ``curves.png``) judges each finished variant against the paper's teacher and against
each noise baseline (one Holm-corrected family per reference over the tasks, ``verdicts``), with the
aggregate over the tasks in ``aggregate.md``; cells not finished are listed as not run.

``VARIANTS`` (``experiments.training.screen_variants``) holds each variant's change and the hypothesis behind it, written before it was run.
A variant whose change is already the task's paper preset (one teacher step per cycle on Hopper) is
skipped on that task.
"""

from __future__ import annotations

import argparse
import functools
import os
import sys

import envs
from experiments import ablation, reproduce
from experiments.analysis import cells, stats
from experiments.grid.methods import task_name
from experiments.grid import engine
from experiments.grid.cli import add_grid_options, check_grid_options, grid_run, grid_spec
from experiments.grid.estimate import add_estimate_options, check_estimate_options
from experiments.grid.spec import Method
from experiments.training import grid_cells
from experiments.training.screen_variants import BASELINES, CONTROL, DEFAULT_STEPS, DEFAULT_TASKS, VARIANTS


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments.screen", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--tasks", default=",".join(DEFAULT_TASKS), help="comma-separated tasks (default hopper,halfcheetah)")
    p.add_argument("--variants", default=",".join(VARIANTS),
                   help="comma-separated variants, run in this order (default all): " + ", ".join(VARIANTS))
    add_grid_options(p, seeds=8, seed=0, steps=DEFAULT_STEPS, physics="mujoco",
                     steps_help=f"env steps per seed (default {DEFAULT_STEPS:,})",
                     physics_help="engine of the MuJoCo tasks (default mujoco, MuJoCo's C engine)",
                     runs_help="cells' run folders (default runs/screen)",
                     results_help="archive and report (default results/screen)")
    p.add_argument("--report-only", action="store_true", help="train nothing; rebuild the report from what is stored")
    p.add_argument("--dry-run", action="store_true", help="print what would run; do nothing")
    add_estimate_options(p, by_default=False)
    return p


@functools.lru_cache(maxsize=None)
def _options(task: str, name: str, physics: str) -> Method | None:
    """The variant's method on ``task`` with its change (None where its change is the task's preset already),
    cached: ``same_as`` compares every earlier variant's on the task."""
    from metapg_jax.config import make_config

    v = VARIANTS[name]
    sets = v.sets(make_config(task, "meta", physics=physics))
    return None if sets is None else v.method.setting(*sets)


def same_as(task: str, name: str, physics: str) -> str | None:
    """Why the variant has no cell of its own on ``task``: '' where its change is the task's preset already,
    else the earlier variant whose cell it would repeat; None where it has its own cell."""
    options = _options(task, name, physics)
    if options is None:
        return ""
    for other in VARIANTS:
        if other == name:
            return None
        if _options(task, other, physics) == options:
            return other
    return None


def cell_options(task: str, name: str, physics: str) -> Method | None:
    """The variant's method on ``task``; None where it has no cell of its own there (``same_as``)."""
    return None if same_as(task, name, physics) is not None else _options(task, name, physics)


def plan(a: argparse.Namespace) -> list[grid_cells.Cell]:
    """Every cell to run, configs validated before anything trains."""
    tasks = reproduce.parse_list(a.tasks, tuple(envs.TASKS), "task")
    names = reproduce.parse_list(a.variants, tuple(VARIANTS), "variant")
    check_grid_options(a, trains=not a.report_only and not a.dry_run)
    # Each run's own PNGs are never drawn: the report draws the curves.
    placement = grid_run(a, a.runs_dir, a.results_dir, "paper", BASELINES[0], no_plot=True)
    spec = grid_spec(a, "paper")
    out = [grid_cells.grid_cell(placement, spec, task, name, options, key=(task, name), tag=f"{task}/{name}")
           for task in tasks for name in names if (options := cell_options(task, name, a.physics)) is not None]
    check_estimate_options(a, tasks)
    grid_cells.validate_cells(out)
    return out


# ------------------------------------------------------------------------------------------------ report

def task_rows(results_dir: str, task: str, upto: int) -> tuple[list[dict], list[str]]:
    """ablation.compare rows of the task's finished cells (control first) and the variants not finished."""
    root = os.path.join(results_dir, "cells", task)
    runs, missing = [], []
    for name in VARIANTS:
        path = os.path.join(root, name)
        r = cells.load_run(path) if os.path.exists(os.path.join(path, "summary.json")) else None
        if r is None or r.env_steps_done < upto:
            missing.append(name)
            continue
        runs.append((name, r))
    if not runs or runs[0][0] != CONTROL:
        return [], [n for n in VARIANTS]
    return ablation.compare(runs, upto), missing


def verdicts(by_task: dict, anchors: dict | None = None) -> dict:
    """The screen's corrected verdicts (``stats.VerdictFamily``), one family per reference, over every task:
    each variant against the paper's teacher, and each teacher variant (not the noise baselines) against each
    noise baseline. ``{reference: {(task, variant): judged}}``; margins: ``stats.EQUIVALENCE_MARGIN`` of the
    task's anchors' range (none without anchors)."""
    out = {}
    for ref in (CONTROL, *BASELINES):
        family = stats.VerdictFamily(anchors)
        for task, (rows, _) in by_task.items():
            found = {r["name"]: r for r in rows}
            if ref not in found:
                continue
            for r in rows:
                if r["name"] == ref or (ref in BASELINES and r["name"] in BASELINES):
                    continue
                family.add((task, r["name"]), r["finals"], found[ref]["finals"], task)
        out[ref] = dict(family.judge())
    return out


def _said(judged: dict | None) -> str:
    return "–" if judged is None else f"{judged['verdict']} ({stats.fmt_p(judged['p'])}; {stats.fmt_p(judged['p_holm'])})"


def markdown(by_task: dict, upto: int, seeds: int, build: dict, physics: str = "mujoco",
             judged: dict | None = None) -> str:
    """The report; ``by_task``: task -> ``task_rows``' (rows, missing); ``judged``: ``verdicts``' result."""
    tasks = list(by_task)
    judged = verdicts(by_task) if judged is None else judged
    lines = [f"# Screen of teacher variants ({', '.join(task_name(t) for t in tasks)}, {upto:,} env steps, "
             f"{seeds} seeds)", "",
             "Algorithm 1's knobs changed one at a time from the paper preset (`python -m experiments.screen`, "
             "MuJoCo's C engine, base seed 0), next to the paper's teacher and both DDPG noise baselines on the "
             "same seeds and budget. Final return of a seed = mean of its last 10% (at least 1) evaluations; "
             "mean ± std over seeds (ddof=1); 95% CI: Student t. Each verdict column is one family over both tasks "
             "(every variant against the paper's teacher; every teacher variant against each noise baseline), "
             "written 'verdict (raw p; Holm p)': " + stats.VERDICT_DEFINITION + ". Aggregate scores over the tasks: "
             "`aggregate.md`. Per task: "
             "`<task>/README.md` (what changed, from the stored configs; teacher log-std), `<task>/per_seed.csv`, "
             "`<task>/curves.png`; cells: `cells/<task>/<variant>`.", "",
             "## Variants and the hypotheses behind them", "",
             "Each written before its variant ran (the variance-teacher and teacher-lr entries after the paper "
             "teacher's Hopper cell, whose metrics they cite: `cells/hopper/paper-teacher/metrics.jsonl`; the "
             "combinations after the single changes' cells).", "", "| variant | change | hypothesis |", "|---|---|---|"]
    for name, v in VARIANTS.items():
        lines.append(f"| {v.label} | {v.change} | {v.hypothesis} |")
    for task in tasks:
        rows, missing = by_task[task]
        lines += ["", f"## {task_name(task)}", ""]
        if not rows:
            lines.append(f"The paper teacher's cell is not finished: nothing is compared ({len(VARIANTS)} cells "
                         "not run or not finished).")
            continue
        lines += ["| variant | final (mean ± std) | 95% CI | vs paper teacher | "
                  + " | ".join(f"vs {VARIANTS[b].label}" for b in BASELINES)
                  + " | teacher log-std | seeds at floor |", "|---|---|---|---|" + "---|" * len(BASELINES) + "---|---|"]
        for r in rows:
            said = [_said(judged[ref].get((task, r["name"]))) for ref in (CONTROL, *BASELINES)]
            t = r["teacher"]
            lines.append(f"| {VARIANTS[r['name']].label} | {stats.fmt(r['mean'])} ± {stats.fmt(r['std'])} | "
                         f"± {stats.fmt(r['ci_half'])} | {' | '.join(said)} | "
                         f"{'–' if t is None else stats.fmt(t['mean'], 2)} | "
                         f"{'–' if t is None else str(t['seeds_at_floor']) + ' of ' + str(len(t['per_seed']))} |")
        why = {n: same_as(task, n, physics) for n in missing}
        skipped = [n for n in missing if why[n] == ""]
        repeats = [n for n in missing if why[n]]
        pending = [n for n in missing if why[n] is None]
        if skipped:
            lines.append("")
            lines.append("Not a change on this task (its preset already has it): "
                         + ", ".join(VARIANTS[n].label for n in skipped) + ".")
        if repeats:
            lines.append("")
            lines.append("The same config as an earlier variant on this task (not run twice): "
                         + ", ".join(f"{VARIANTS[n].label} = {VARIANTS[why[n]].label}" for n in repeats) + ".")
        if pending:
            lines.append("")
            lines.append("Not run (or not finished) yet: " + ", ".join(VARIANTS[n].label for n in pending) + ".")
    dirty = cells.dirty_summary([cells.load_run(r["path"], task, r["name"]) for task in tasks
                                 for r in by_task[task][0]])
    lines += ["", "---", "", f"Built {build['built']} at commit `{build.get('commit') or 'unknown'}` on "
              f"{build['machine']['platform']}." + (f" {dirty}" if dirty else "") + " Each cell's commit, config, "
              "seeds, budget, machine and wall time: `cells/<task>/<variant>/reproduce.json` and `config.json` "
              "(`verified.json` where a cell was re-run from its commit); summary: `screen.json`."]
    return "\n".join(lines) + "\n"


def write_report(results_dir: str, tasks: list[str], upto: int, seeds: int, physics: str = "mujoco",
                 anchors_path: str | None = None) -> list[str]:
    """README.md (the tables with corrected verdicts), screen.json, the aggregate over the tasks (aggregate.md /
    .json, performance_profiles.png: the variants finished on every task, normalised with ``anchors_path``,
    default results/normalisation.json) and per task ``experiments.ablation``'s report."""
    from experiments import aggregate, normalisation
    from metapg_jax.host import runfiles

    anchors_path = normalisation.DEFAULT_OUT if anchors_path is None else anchors_path
    anchors = normalisation.load(anchors_path) if os.path.exists(anchors_path) else None
    build = cells.build_info(results_dir)
    files, summary, by_task = [], {"upto": upto, "seeds": seeds, "build": build, "tasks": {}}, {}
    for task in tasks:
        rows, missing = by_task[task] = task_rows(results_dir, task, upto)
        if rows:
            files += ablation.write_report(rows, task, upto, os.path.join(results_dir, task), build)
    judged = verdicts(by_task, anchors)
    for task, (rows, missing) in by_task.items():
        summary["tasks"][task] = {
            "finished": {r["name"]: {"finals": [float(x) for x in r["finals"]], "mean": r["mean"], "std": r["std"],
                                     "ci_half": r["ci_half"], "commit": r["commit"],
                                     "teacher_log_std": None if r["teacher"] is None else r["teacher"]["mean"],
                                     "verdicts": {ref: judged[ref][(task, r["name"])] for ref in judged
                                                  if (task, r["name"]) in judged[ref]}}
                         for r in rows},
            "not_finished": missing}
    summary["verdicts_definition"] = stats.VERDICT_DEFINITION
    os.makedirs(results_dir, exist_ok=True)
    md = os.path.join(results_dir, "README.md")
    with open(md, "w") as f:
        f.write(markdown(by_task, upto, seeds, build, physics, judged))
    runfiles.write_json_atomic(os.path.join(results_dir, "screen.json"), summary)
    # A variant with no cell of its own on a task stands for the cell it equals there (its change is the task's
    # preset: the paper teacher's; or the same config as an earlier variant's), as the tables say.
    finished = {task: {r["name"]: r["finals"] for r in rows} for task, (rows, _) in by_task.items()}
    same = {(task, n): same_as(task, n, physics) for task in finished for n in VARIANTS}
    stands_for = {k: CONTROL if v == "" else v or k[1] for k, v in same.items()}
    everywhere = [n for n in VARIANTS if all(stands_for[(t, n)] in finished[t] for t in finished)]
    grid = {"rows": [{"task": task, "methods": {n: {"status": "done", "per_seed": list(finished[task][stands_for[(task, n)]])}
                                                for n in everywhere}} for task in finished]}
    scored = aggregate.grid_scores(grid, anchors) if anchors is not None and everywhere else None
    if scored and scored[0]:
        rep = aggregate.report(grid, anchors, scored)
        rep["variants_not_on_every_task"] = [n for n in VARIANTS if n not in everywhere]
        rep["standing_for"] = {f"{t}/{n}": o for (t, n), o in stands_for.items() if o != n and n in everywhere}
        files += aggregate.write(rep, scored, results_dir, "screen", {
            "date": build["built"][:10], "commit": build["commit"], "dirty": build["dirty"],
            "grid": "screen.json", "anchors": aggregate.repo_path(anchors_path)},
            labels={n: v.label for n, v in VARIANTS.items()})
    return [md, os.path.join(results_dir, "screen.json")] + files


def main(argv: list[str] | None = None) -> int:
    return run_parsed(build_parser().parse_args(argv))


def run_parsed(a: argparse.Namespace, argv: list[str] | None = None) -> int:
    """``main`` after parsing (``experiments.grid`` runs a named study through it)."""
    del argv  # the report records no command line
    return engine.run(a, lambda: grid_plan(a), report_only=a.report_only)


def grid_plan(a: argparse.Namespace) -> engine.GridPlan:
    """The screen's cells (``plan``) and its report (``write_report``)."""
    a.runs_dir = a.runs_dir or "runs/screen"
    a.results_dir = a.results_dir or "results/screen"
    todo = plan(a)
    tasks = list(dict.fromkeys(cell.task for cell in todo)) or reproduce.parse_list(a.tasks, tuple(envs.TASKS), "task")

    def report(wall_seconds: float) -> None:
        del wall_seconds
        print("wrote " + ", ".join(write_report(a.results_dir, tasks, a.steps, a.seeds, a.physics)), flush=True)

    return engine.GridPlan(todo, tasks, report, word="screen")

if __name__ == "__main__":
    sys.exit(main())
