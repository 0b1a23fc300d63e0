"""The behaviour and coverage tables as files: ``behaviour.md`` / ``.json`` from
``experiments.analysis.behaviour.behaviour_rows`` and ``coverage.md`` / ``.json`` from its ``coverage_rows``
(what the explorers put in the buffer; how much of the state space each data source covers)."""

from __future__ import annotations

import os

from experiments.analysis.behaviour import BEHAVIOUR_COLUMNS, COVERAGE_DEFINITION, COVERAGE_GROUPS
from experiments.analysis.render.tables import write_md_and_json
from experiments.analysis.stats import fmt
from experiments.grid.methods import METHOD_NAMES, grid_label, task_name


def write_behaviour(rows: list[dict], out_dir: str, footer: str, preset: str, build_commit: str | None = None,
                    student: str = "ddpg") -> list[str]:
    """behaviour.md and behaviour.json from ``behaviour_rows``; returns the paths."""
    paths = [os.path.join(out_dir, "behaviour.md"), os.path.join(out_dir, "behaviour.json")]
    md = [f"# What the explorer put in the buffer ({grid_label(preset, student)})", "",
          "From the per-chunk training metrics of the finished cells (`metrics.jsonl`), next to the final "
          "evaluation return:", "",
          "- exploration-episode return: the mean return of the episodes that ended during a chunk's exploration "
          "rollouts: DDPG's student with its noise (Gaussian, OU) or perturbed weights (param noise); Meta's "
          "teacher collecting D0 (D1, the student's deterministic rollouts that also go to the buffer, is not "
          "counted). Chunks in which no episode ended are left out.",
          "- teacher log-std: the mean over D0's states and action dimensions; teacher-student distance: the RMS "
          "difference between the teacher's action and the student's deterministic action on D0's states "
          "(actions in [-1, 1]); meta reward: R_hat(pi') - R_hat(pi) (Algorithm 1).",
          "- first: the seed mean of the first chunk (the first evaluation interval); final: mean ± std over "
          "seeds of each seed's mean over the final return's window (the last max(1, floor(T/10)) chunks)."]
    for task in dict.fromkeys(r["task"] for r in rows):
        md += ["", f"## {task_name(task)}", "",
               "| method | seeds | final evaluation return | " +
               " | ".join(f"{label}, first | {label}, final" for _, label in BEHAVIOUR_COLUMNS) + " |",
               "|---|---|---|" + "---|---|" * len(BEHAVIOUR_COLUMNS)]
        for r in (r for r in rows if r["task"] == task):
            cols = []
            for k, _ in BEHAVIOUR_COLUMNS:
                v = r.get(k)
                cols += ["–", "–"] if v is None else [fmt(v["first"]), f"{fmt(v['final_mean'])} ± {fmt(v['final_std'])}"]
            md.append(f"| {METHOD_NAMES.get(r['method'], r['method'])} | {r['n']} | {fmt(r['eval_final'])} | "
                      + " | ".join(cols) + " |")
    if not rows:
        md += ["", "(no finished cell logged its exploration metrics)"]
    md.append(footer)
    write_md_and_json(paths[0], md, paths[1], preset, student, {"build_commit": build_commit, "rows": rows})
    return paths


def write_coverage(coverage: dict, out_dir: str, footer: str, preset: str, baseline: str,
                   build_commit: str | None = None, student: str = "ddpg") -> list[str]:
    """coverage.md and coverage.json from ``coverage_rows``; returns the paths (none when no task has both
    visitation samples)."""

    if not coverage["rows"]:
        return []
    paths = [os.path.join(out_dir, "coverage.md"), os.path.join(out_dir, "coverage.json")]
    names = dict(COVERAGE_GROUPS, ddpg=METHOD_NAMES.get(baseline, baseline))
    measures = {"occupied": "occupied cells", "spread": "5-NN spread", "to_student": "distance to the student"}
    ci = lambda e: f"{fmt(e['mean'], 3)} [{fmt(e['lo'], 3)}, {fmt(e['hi'], 3)}]"
    md = [f"# State coverage of the visited states ({grid_label(preset, student)})", "",
          "The numbers behind the state-visitation figures (`visitation_<task>.png`, the paper's Figure 4): how "
          "much of the state space each explorer's data covers and how far the teacher's states lie from the "
          "student's, from the same stored samples (the first and the latest states each seed visited).", "",
          f"- {COVERAGE_DEFINITION}.",
          "- comparisons: teacher − noise baseline (independent runs: each group's seeds resampled on their own) "
          "and the teacher's distance to the student's states − the student's own (the same runs: paired by "
          "seed); 'higher' / 'lower' where the 95% interval excludes 0."]
    for task in dict.fromkeys(r["task"] for r in coverage["rows"]):
        rows = [r for r in coverage["rows"] if r["task"] == task]
        md += ["", f"## {task_name(task)}", "",
               f"{rows[0]['states_per_seed']} states per seed and group.", "",
               "| phase | group | seeds | " + " | ".join(measures.values()) + " |", "|---|---|---|---|---|---|"]
        for r in rows:
            md.append(f"| {r['phase']} | {names[r['group']]} | {r['seeds']} | "
                      + " | ".join(ci(r[m]) for m in measures) + " |")
        comps = [c for c in coverage["comparisons"] if c["task"] == task]
        md += ["", "| phase | measure | comparison | difference [95% CI] | reading |", "|---|---|---|---|---|"]
        for c in comps:
            md.append(f"| {c['phase']} | {measures[c['measure']]} | {c['comparison']} | "
                      f"{fmt(c['difference'], 3)} [{fmt(c['lo'], 3)}, {fmt(c['hi'], 3)}] | {c['reading']} |")
    md.append(footer)
    write_md_and_json(paths[0], md, paths[1], preset, student,
                       {"baseline": baseline, "definition": COVERAGE_DEFINITION, "build_commit": build_commit,
                        **coverage})
    return paths
