"""A results folder's ``README.md``: what each artefact is, which cells were run, and the headline numbers."""

from __future__ import annotations

import os
from typing import Sequence

from experiments.grid.methods import METHOD_NAMES, baseline_for, grid_label, task_name
from experiments.analysis.stats import fmt_p
from experiments.analysis.render.tables import cell_text
from experiments.analysis.tables import verdict_families


def write_readme(out_dir: str, manifest: dict, rows: list[dict], methods: Sequence[str], footer: str,
                 families: list[dict] | None = None) -> str:
    """``README.md``: what each artefact is, which cells were run, and the headline numbers (the final returns
    and the corrected verdicts against the grid's baseline, ``verdict_families``' first family)."""
    preset, student = manifest["build"]["preset"], manifest["build"].get("student", "ddpg")
    baseline = METHOD_NAMES.get(baseline_for(preset, student), baseline_for(preset, student))
    cells = manifest["cells"]
    done = [c for c in cells if c["complete"]]
    have = set(manifest["files"])
    lines = [f"# Results ({grid_label(preset, student)})", "",
             f"Rebuilt by `python -m experiments.reproduce --artefacts-only` (or `python -m experiments.artefacts`) "
             f"from the run folders under `{manifest['build']['runs_dir']}/{preset}/<task>/<method>` (not committed) "
             f"and, for cells without a finished run folder, the committed copies of finished cells in "
             f"`cells/<task>/<method>` (config, metrics, summary, provenance, thinned visitation sample). "
             f"{len(done)} finished and {len(cells) - len(done)} unfinished cells are stored; "
             f"{len(manifest['not_run'])} cells of the grid were not run.", "",
             "| file | content |", "|---|---|"]
    desc = {
        "table2.md": "the paper's Table 2: final return mean ± std per task and method, 95% CIs, budget and seeds, "
                     "next to the paper's numbers; the verdicts against each noise baseline (Holm-corrected, "
                     "equivalence within a declared margin)",
        "table2.json": "the same, machine-readable (with per-seed final returns)",
        "table2_per_seed.csv": "per-seed final returns of every finished cell",
        "steps_to_threshold.md": "first env step at which each method's seed-mean curve reaches DDPG's best "
                                 "(and the ratio to DDPG's step)",
        "steps_to_threshold.csv": "steps-to-threshold as CSV (threshold, step, DDPG step, ratio per task and method)",
        "comparisons.md": "every method against every other per task: medians, ranges, best seed means, "
                          "differences, Welch p, at how many evaluations one seed-mean curve is above the other",
        "comparisons.json": "the same, machine-readable",
        "behaviour.md": "what the explorer put in the buffer per cell: the exploration episodes' return and, for a "
                        "teacher, its log-std, distance to the student and meta reward, first chunk vs final window",
        "behaviour.json": "the same, machine-readable",
        "coverage.md": "state coverage as numbers behind the visitation figures: occupied cells of a fixed 2-D grid, "
                       "k-NN spread and distance to the student's states per group, early vs late, with bootstrap "
                       "intervals, and the teacher's against the noise baseline's and the student's",
        "coverage.json": "the same, machine-readable",
        "teacher_designs_idp.png": "Figure 2: independent vs variance teacher vs DDPG on InvertedDoublePendulum",
        "manifest.json": "provenance: commit, machine, and per cell config, seeds, budget, wall time",
        "aggregate.md": "aggregate scores over the tasks (IQM, mean, optimality gap of normalised final returns) "
                        "and the probability of improvement, with 95% stratified bootstrap intervals",
        "aggregate.json": "the same, machine-readable, with the normalisation anchors used",
        "performance_profiles.png": "performance profiles: the fraction of seeds above each normalised score",
    }
    for f in manifest["files"]:
        if f == "README.md":
            continue
        if f.startswith("curves_"):
            d = f"Figure 3: learning curves on {f[7:-4]}, mean ± std over seeds per method"
        elif f.startswith("visitation_"):
            d = f"Figure 4: states visited by teacher, student and DDPG, early vs late, on {f[11:-4]}"
        elif f.startswith("teacher_designs_"):
            d = desc["teacher_designs_idp.png"] if f == "teacher_designs_idp.png" else "teacher designs vs DDPG"
        else:
            d = desc.get(f, "")
        lines.append(f"| `{f}` | {d} |")
    lines.append("| `manifest.json` | " + desc["manifest.json"] + " |")
    absent = manifest.get("grid_without_cells", {})
    if absent.get("tasks") or absent.get("methods"):
        lines += ["", "Left out of the tables (the grid has no cell stored for them): "
                  + "; ".join(part for part in (
                      ", ".join(task_name(t) for t in absent.get("tasks", [])),
                      ", ".join(METHOD_NAMES.get(m, m) for m in absent.get("methods", []))) if part) + "."]
    if manifest.get("aggregate_not_built"):
        lines += ["", f"No aggregate scores: {manifest['aggregate_not_built']}."]
    if "teacher_designs_idp.png" not in have:
        lines += ["", "No InvertedDoublePendulum run is stored, so `teacher_designs_idp.png` (Figure 2) is not built."]
    if not any(f.startswith("visitation_") for f in have):
        lines += ["", f"No task has both a Meta (independent) and a {baseline} run with `visits.npz`, so the "
                      "state-visitation figure is not built."]
    lines += ["", "## Final return (mean ± std over seeds; see `table2.md` for definitions and CIs)", "",
              "| task | " + " | ".join(METHOD_NAMES.get(m, m) for m in methods)
              + f" | verdict against {baseline} (Holm p) |", "|---|" + "---|" * len(methods) + "---|"]
    fixed = (families or verdict_families(rows, methods, baseline_for(preset, student)))[0]["comparisons"]
    for row in rows:
        said = "; ".join(f"{METHOD_NAMES.get(c['method'], c['method'])}: {c['verdict']} ({fmt_p(c['p_holm'])})"
                         for c in fixed if c["task"] == row["task"])
        lines.append(f"| {task_name(row['task'])} | " +
                     " | ".join(cell_text(row["methods"][m]) for m in methods) + f" | {said or 'not compared'} |")
    lines.append(footer)
    path = os.path.join(out_dir, "README.md")
    with open(path, "w") as f:
        f.write("\n".join(lines))
    return path
