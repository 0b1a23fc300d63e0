"""The learned-exploration diagnostics' files and command (``python -m experiments.analysis.learned``, whose module
docstring says what is computed): ``diagnostics.md``, ``diagnostics.json`` and the meta reward figure, from what
``experiments.analysis.learned`` computes."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

from experiments.analysis import stats
from experiments.analysis.cells import ARCHIVE_CYCLES
from experiments.analysis.learned import (ARTEFACTS_FIRST, GOAL, LAST, LEARNED, build, goal, load_plan, planned,
                                          read_cycles)
from experiments.grid.methods import METHOD_NAMES, STUDENT_NAMES, task_folder, task_name


FIGURE = "meta_reward.png"


def meta_reward_figure(results_dir: str, cells: list[dict], path: str) -> bool:
    """``plots.plot_meta_rewards`` of the finished cells of a ``build`` report (one panel per student and task);
    False (nothing written) when no cell is finished."""
    from experiments.analysis.render import plots

    panels: dict[tuple[str, str], dict[str, list[dict]]] = {}
    for c in cells:
        if c["state"] != "finished":
            continue
        d = os.path.join(results_dir, c["student"], "cells", task_folder(c["task"]), c["method"])
        rows = [r for rs in read_cycles(os.path.join(d, ARCHIVE_CYCLES)).values() for r in rs]
        panels.setdefault((STUDENT_NAMES.get(c["student"], c["student"]), task_name(c["task"])), {})[
            _name(c["method"])] = rows
    if not panels:
        return False
    plots.plot_meta_rewards(panels, path, "Meta reward per cycle (mean over seeds of a moving average over 5% "
                                          "of the run)")
    return True


def _f(x, digits=2) -> str:
    return "–" if x is None or (isinstance(x, float) and not math.isfinite(x)) else stats.fmt(x, digits)


def _name(method: str) -> str:
    return METHOD_NAMES.get(method, method)


def _verdict_cells(row: dict) -> str:
    if row["state"] != "compared":
        return f"– | – | – | – | {row['state']}"
    f = lambda x: _f(x, None)
    ci = "" if row["ci95"] is None else f" [{f(row['ci95'][0])}, {f(row['ci95'][1])}]"
    return (f"{f(row['mean_a'])} vs {f(row['mean_b'])} | {f(row['difference'])}{ci} | "
            f"{stats.fmt_p(row['p'])} | {stats.fmt_p(row['p_holm'])} | {row['verdict']}")


def _predictions_markdown(student: str, pred: dict, anchors: str | None) -> list[str]:
    n = sum(r["state"] == "compared" for r in pred["comparisons"])
    m = sum(r["state"] == "compared" for r in pred["controls"])
    lines = ["", f"## {student}: the hypotheses' predictions"]
    if pred["comparisons"]:
        lines += ["", f"Final returns (mean of each seed's last 10% of evaluations): Welch tests, Holm-corrected "
                  f"over the {n} comparisons made; 'equivalent' only by the TOST of ±{stats.EQUIVALENCE_MARGIN:.0%} "
                  "of the task's normalisation range (" + (f"`{anchors}`; " if anchors else "no anchors: ")
                  + "a task without anchors is never equivalent). 'beats' is met by 'better' and "
                  "refuted by 'worse' or 'equivalent'; 'not worse' is met by 'better' or 'equivalent' and refuted by "
                  "'worse'; otherwise it is inconclusive.", "",
                  "| hypothesis | prediction | task | a vs b (mean final) | a − b [95% CI] | p | Holm p | verdict | "
                  "outcome |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for r in pred["comparisons"]:
            lines.append(f"| {r['hypothesis']} | {_name(r['a'])} {r['prediction']} {_name(r['b'])} | "
                         f"{task_name(r['task'])} | {_verdict_cells(r)} | {r['outcome']} |")
    if pred["diagnostics"]:
        lines += ["", "| hypothesis | prediction (diagnostics) | method | task | measured | outcome |",
                  "|---|---|---|---|---|---|"]
        for r in pred["diagnostics"]:
            lines.append(f"| {r['hypothesis']} | {r['prediction']} | {_name(r['method'])} | "
                         f"{task_name(r['task'])} | {_f(r['value'])} | {r['outcome']} |")
    if pred["controls"]:
        lines += ["", f"What each variant adds over each control (H4): a family of its own, Holm-corrected over its "
                  f"{m} comparisons made (the pairs above are judged there only).", "",
                  "| variant | control | task | a vs b (mean final) | a − b [95% CI] | p | Holm p | verdict |",
                  "|---|---|---|---|---|---|---|---|"]
        for r in pred["controls"]:
            lines.append(f"| {_name(r['a'])} | {_name(r['b'])} | {task_name(r['task'])} | {_verdict_cells(r)} |")
    if len(lines) == 2:
        lines += ["", "None: the grid planned none of the strategies the predictions name."]
    return lines


def _p_text(r: dict) -> str | None:
    """A goal row's P(variant > baseline) with its interval, '0.37 [0.25, 0.51]'; None where it was not computed."""
    return f"{r['p']:.2f} [{r['lo']:.2f}, {r['hi']:.2f}]" if "p" in r else None


def _goal_markdown(report: dict) -> list[str]:
    lines = ["", "## The judgement's goal", "",
             f"Goal: {GOAL}. P(X > Y): the benchmark's probability of improvement over the tasks (`aggregate.json`, "
             "95% stratified bootstrap CI; per task: the terms it averages); verdicts: against the student's "
             "baseline, Holm-corrected over the student's family, every one of its strategies on every task "
             "(`tasks/<task>.json`).", "",
             "| student | variant | baseline | P(variant > baseline) [95% CI] | per task | worse on | better on | "
             "goal |",
             "|---|---|---|---|---|---|---|---|"]
    for student, g in report["goal"].items():
        for r in g["variants"]:
            p = _p_text(r) or "–"
            per = ", ".join(f"{task_name(t)} {x:.2f}" for t, x in r["per_task"].items()) if "p" in r else "–"
            names = lambda ts: ", ".join(task_name(t) for t in ts) or "none"
            lines.append(f"| {STUDENT_NAMES.get(student, student)} | {_name(r['method'])} | {_name(g['baseline'])} | "
                         f"{p} | {per} | {names(r['worse'])} | {names(r['better'])} | {r['outcome']} |")
    return lines


def markdown(report: dict) -> str:
    last = report["last"]
    lines = ["# Learned exploration: diagnostics of the variants and controls, and the hypotheses' predictions", "",
             f"From each finished cell's archived per-cycle metrics (`cycles.jsonl.gz`), over each seed's last {last} "
             "cycles, pooled over seeds. Meta reward spread: the root mean square over cycles of the spread (sample "
             "std) over the cycle's eval envs of the per-env differences R_hat(pi') - R_hat(pi) from the same resets "
             "(paired), and of what the difference of independent rollouts would spread, sqrt(sd(R_hat(pi'))^2 + "
             "sd(R_hat(pi))^2) (unpaired); ratio: paired over unpaired (about 1 where pairing changes nothing). "
             "Meta reward mean ± std: over the cycles; SNR = |mean| / std; seeds' std: the standard deviation over "
             "seeds of each seed's mean meta reward (the spread to compare two cells' means by). Distance: "
             "the RMS teacher-student action distance on D0 (actions in [-1, 1]), mean ± std over seeds of each "
             "seed's mean; of the teacher's mean: the same for the mean of its action distribution (clipped to "
             "[-1, 1]), its noise left out ('–': not recorded). Bandit: per seed the scale chosen most often and "
             "its share of the cycles.", "",
             "| student | task | method | seeds | spread paired | spread unpaired | ratio | meta reward mean ± std | "
             "SNR | seeds' std | distance | of the teacher's mean | bandit: seeds whose favourite has > 1/2 | "
             "bandit: favourite scales (seeds) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for c in report["cells"]:
        head = f"| {STUDENT_NAMES.get(c['student'], c['student'])} | {task_name(c['task'])} | " \
               f"{METHOD_NAMES.get(c['method'], c['method'])} |"
        if c["state"] != "finished":
            lines.append(head + f" {c['state']} |" + " |" * 10)
            continue
        b = c.get("bandit")
        lines.append(head + f" {c['seeds']} | {_f(c['sd_paired_rms'], 3)} | {_f(c['sd_unpaired_rms'], 3)} | "
                     f"{_f(c['sd_ratio'])} | {_f(c['meta_reward_mean'], 3)} ± {_f(c['meta_reward_std'], 3)} | "
                     f"{_f(c['meta_reward_snr'])} | {_f(c['meta_reward_seed_std'], 3)} | "
                     f"{_f(c['distance_mean'])} ± {_f(c['distance_std'])} | "
                     + ("–" if c.get("mean_distance_mean") is None else
                        f"{_f(c['mean_distance_mean'])} ± {_f(c['mean_distance_std'])}") + " | "
                     + (f"{b['seeds_over_half']} of {c['seeds']} | "
                        + ", ".join(f"{k} ({v})" for k, v in b["favourite_counts"].items()) + " |" if b else "– | – |"))
    if report.get("figure"):
        lines += ["", f"The meta reward over training, every finished cell (`{report['figure']}`):", "",
                  f"![meta reward per cycle]({report['figure']})"]
    if "goal" in report:
        lines += _goal_markdown(report)
    for student, pred in report.get("predictions", {}).items():
        lines += _predictions_markdown(STUDENT_NAMES.get(student, student), pred, report.get("anchors"))
    b = report["built"]
    lines += ["", "---", "", f"Built {b['built']} from `{b['runs_dir']}` at commit `{b['commit']}`"
              + (" (uncommitted changes)" if b.get("dirty") else "") + f" on {b['machine']['platform']}."]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    from experiments.analysis import learned

    p = argparse.ArgumentParser(prog="python -m experiments.analysis.learned", description=learned.__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--results-dir", default="results/learned/screen", help="a benchmark's results folder")
    p.add_argument("--tasks", default=None,
                   help="comma-separated tasks (default: the grid's, from its manifest; else hopper,halfcheetah)")
    p.add_argument("--students", default="td3", help=f"comma-separated students of {', '.join(LEARNED)} (default td3)")
    p.add_argument("--last", type=int, default=LAST, help=f"cycles per seed at the end of training (default {LAST})")
    p.add_argument("--goal", action="store_true",
                   help="also judge the judgement's goal against each student's baseline (module docstring)")
    p.add_argument("--no-plot", action="store_true", help=f"do not draw {FIGURE}")
    p.add_argument("--anchors", default=None,
                   help="normalisation anchors of the equivalence margins (default results/normalisation.json; "
                        "without them nothing is judged equivalent)")
    a = p.parse_args(argv)
    students = [s for s in a.students.split(",") if s]
    bad = [s for s in students if s not in LEARNED]
    if bad or not students or a.last <= 0:
        print(f"error: students must be among {', '.join(LEARNED)} and --last positive", file=sys.stderr)
        return 2
    if not os.path.isdir(a.results_dir):
        print(f"error: no folder {a.results_dir!r}", file=sys.stderr)
        return 2
    plan = load_plan(a.results_dir)
    tasks = [t for t in (a.tasks or ",".join(plan["tasks"] if plan else ("hopper", "halfcheetah"))).split(",") if t]
    if not tasks:
        print("error: --tasks is empty", file=sys.stderr)
        return 2
    if plan is not None:
        unplanned = [s for s in students if s not in planned(plan)] + [t for t in tasks if t not in plan["tasks"]]
        if unplanned:
            print(f"error: {', '.join(unplanned)} not in the grid's plan (students {', '.join(planned(plan))}; tasks "
                  f"{', '.join(plan['tasks'])})", file=sys.stderr)
            return 2
    if a.goal and plan is None:
        print(f"error: --goal needs the benchmark's manifest.json in {a.results_dir} ({ARTEFACTS_FIRST})",
              file=sys.stderr)
        return 2
    if a.goal and set(tasks) != set(plan["tasks"]):
        print(f"error: --goal judges the grid's tasks ({', '.join(plan['tasks'])}), not a part of them",
              file=sys.stderr)
        return 2
    from experiments import normalisation

    if a.anchors is not None and not os.path.isfile(a.anchors):
        print(f"error: no anchors file {a.anchors!r}", file=sys.stderr)
        return 2
    anchors_path = a.anchors or normalisation.DEFAULT_OUT
    anchors = normalisation.load(anchors_path) if os.path.exists(anchors_path) else None
    try:
        judged_goal = goal(a.results_dir, plan, students) if a.goal else None
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    report = build(a.results_dir, tasks, students, a.last, anchors, plan)
    if judged_goal is not None:
        report["goal"] = judged_goal
    report["anchors"] = os.path.relpath(anchors_path) if anchors is not None else None
    if not a.no_plot and meta_reward_figure(a.results_dir, report["cells"], os.path.join(a.results_dir, FIGURE)):
        report["figure"] = FIGURE
    with open(os.path.join(a.results_dir, "diagnostics.json"), "w") as f:
        json.dump(report, f, indent=1)
        f.write("\n")
    with open(os.path.join(a.results_dir, "diagnostics.md"), "w") as f:
        f.write(markdown(report))
    done = sum(c["state"] == "finished" for c in report["cells"])
    print(f"diagnostics of {done} of {len(report['cells'])} cells in {a.results_dir}/diagnostics.md")
    for student, g in (judged_goal or {}).items():
        for r in g["variants"]:
            text = _p_text(r)
            p = f"P = {text}" if text else "P not computed"
            print(f"goal: {STUDENT_NAMES.get(student, student)} {_name(r['method'])} against {_name(g['baseline'])}: "
                  f"{p}, worse on {len(r['worse'])} task(s): {r['outcome']}")
    return 0
