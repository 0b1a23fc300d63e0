"""The paper's artefacts, rebuilt from stored run folders (no training here).

    python -m experiments.artefacts --runs-dir runs/reproduce --results-dir results
    python -m experiments.artefacts --preset modern --embedding pca

Reads a grid of run folders laid out as ``<runs-dir>/<preset>/<task>/<method>``
(what ``experiments.reproduce`` writes; each one an ``experiments.run`` output
folder), copies every finished one into the committed archive
``<results>/cells/<task>/<method>`` (``cells.archive_cell``; run folders hold large
checkpoints and are not committed), reads cells without a finished run folder
from that archive, and writes, under the results folder:

* ``table2.md`` / ``table2.json`` / ``table2_per_seed.csv``: the paper's Table 2
  (rows = tasks, columns = methods): final evaluation return mean ± std over
  seeds, the 95% t confidence interval, Welch's t-test of Meta (independent)
  vs DDPG (parameter noise), the budget and the number of seeds run, next to
  the paper's numbers;
* ``curves_<task>.png``: learning curves, mean ± std band per method (Figure 3);
* ``steps_to_threshold.csv`` / ``.md``: the first env step at which each
  method's seed-mean evaluation return reaches the best seed-mean value of the
  DDPG (parameter noise) baseline, and the ratio to DDPG's own step (the
  paper's "about 1/6 of the samples" claim);
* ``comparisons.md`` / ``.json``: every method against every other per task (medians, ranges, best
  seed means, differences, Welch p, at how many evaluations one seed-mean curve is above the other):
  the numbers docs/results.md quotes beyond Table 2;
* ``behaviour.md`` / ``.json``: what the explorer put in the buffer per finished cell (the return of
  the exploration episodes and, for a teacher, its log-std, its distance to the student and the meta
  reward; first chunk vs final window);
* ``teacher_designs_idp.png``: independent vs variance teacher vs DDPG on
  InvertedDoublePendulum (Figure 2);
* ``visitation_<task>.png``: states visited by the teacher, the student and
  DDPG, early and late, jointly embedded in 2-D with density contours (Figure 4,
  InvertedDoublePendulum in the paper), for every task whose two cells stored them;
* ``README.md`` (what is there and how it was made) and ``manifest.json``
  (provenance: commit, machine, and per cell its config, seeds, budget, wall time).

Every number comes from the stored results; cells without a finished run are
shown as "not run" (or "incomplete"), never estimated.

Definitions (final return, ±, CI, p; also written into the files): ``experiments.analysis.stats``.

Layout: ``experiments.grid.methods`` (tasks, methods, baselines), ``experiments.analysis.stats`` (statistics and
number formatting), ``experiments.analysis.cells`` (reading run folders, the committed archive,
provenance), ``experiments.analysis.tables`` (Table 2, steps to threshold, comparisons, behaviour, README.md),
``experiments.analysis.render.figures`` (curves, teacher designs, visitation); this module rebuilds everything
(``build_all``) and is the command line.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import sys
from typing import Sequence

from experiments.analysis import behaviour, cells, tables
from experiments.analysis.render import behaviour as render_behaviour
from experiments.analysis.render import figures, readme
from experiments.analysis.render import tables as tables_md
from experiments.grid import methods as grid
from experiments.grid.methods import BASELINES, GRIDS, baseline_for, grid_label, methods_for


def build_all(runs_dir: str, results_dir: str, preset: str = "paper", tasks: Sequence[str] | None = None,
              methods: Sequence[str] | None = None, embedding: str = "tsne", visitation_tasks: Sequence[str] | None = None,
              points_per_panel: int = 500, extra_provenance: dict | None = None, student: str = "ddpg",
              anchors_path: str | None = None) -> dict:
    """Rebuilds every artefact from ``<runs_dir>/<preset>/<task>/<method>``; returns the manifest.

    ``tasks`` defaults to the grid's (``experiments.grid.methods.tasks``), ``methods`` to ``student``'s grid
    (``experiments.grid.methods.methods_for``). Finished run folders are
    first copied into the committed archive ``<results>/cells/<task>/<method>`` (``cells.archive_cell``);
    cells without a finished run folder are read from there. The tables show the tasks and methods with a
    stored cell (the grid's others are listed in README.md and the manifest, not shown as "not run").
    ``anchors_path`` (default ``results/normalisation.json``, when it exists): the normalisation anchors of
    the aggregate scores and of the verdicts' equivalence margins."""
    from experiments import aggregate, normalisation

    tasks = grid.tasks() if tasks is None else tasks
    methods = methods_for(student) if methods is None else tuple(methods)
    out_dir = cells.results_dir_for(results_dir, preset)
    os.makedirs(out_dir, exist_ok=True)
    archive = cells.archive_dir_for(results_dir, preset)
    baseline = baseline_for(preset, student)
    for task in tasks:  # every finished run folder is (re)archived before anything is read
        for method in methods:
            cells.archive_cell(os.path.join(runs_dir, preset, task, method), os.path.join(archive, task, method),
                               method, baseline)
    results = cells.collect(os.path.join(runs_dir, preset), tasks, methods, archive_dir=archive)
    planned_tasks, planned_methods = tuple(tasks), tuple(methods)
    tasks = [t for t in planned_tasks if any((t, m) in results for m in methods)]
    methods = [m for m in planned_methods if any((t, m) in results for t in tasks)]
    anchors_path = normalisation.DEFAULT_OUT if anchors_path is None else anchors_path
    anchors = normalisation.load(anchors_path) if os.path.exists(anchors_path) else None
    build = cells.build_info(runs_dir)
    build["preset"] = preset
    if student != "ddpg":
        build["student"] = student
    if extra_provenance:
        build.update(extra_provenance)
    footer = cells.provenance_footer(build, results.values())
    rows = tables.table2_rows(results, tasks, methods, baseline)
    families = tables.verdict_families(rows, methods, baseline, anchors)
    files = tables_md.write_table2(rows, methods, out_dir, footer, preset, build["commit"],
                                tables_md.engines_text(results.values()), student=student, families=families)
    aggregate_note = None
    if anchors is None:
        aggregate_note = f"no normalisation anchors ({aggregate.repo_path(anchors_path)} not found)"
    else:
        scored = aggregate.grid_scores({"rows": rows}, anchors)
        if len(scored[1]) < 2:
            aggregate_note = "the grid has one method with a finished cell, nothing to compare it with"
        elif scored[0]:
            rep = aggregate.report({"rows": rows}, anchors, scored)
            files += aggregate.write(rep, scored, out_dir, grid_label(preset, student), {
                "date": build["built"][:10], "commit": build["commit"], "dirty": build["dirty"],
                "grid": "table2.json", "anchors": aggregate.repo_path(anchors_path)})
        else:
            aggregate_note = "no task has a finished cell for every method: " + "; ".join(scored[3])
    if aggregate_note:
        _remove_stale(out_dir, ("aggregate.md", "aggregate.json", "performance_profiles.png"))
    files += figures.write_curves(results, tasks, methods, out_dir, build, preset, student=student)
    files += tables_md.write_steps_to_threshold(tables.steps_to_threshold_rows(results, tasks, methods, baseline),
                                             out_dir, footer, preset, build["commit"], student=student)
    files += tables_md.write_comparisons(tables.comparison_rows(results, tasks, methods), out_dir, footer, preset,
                                      build["commit"], student=student)
    files += render_behaviour.write_behaviour(behaviour.behaviour_rows(results, tasks, methods), out_dir, footer, preset,
                                    build["commit"], student=student)
    _remove_stale(out_dir, ("coverage.md", "coverage.json"))
    files += render_behaviour.write_coverage(behaviour.coverage_rows(results, tasks, baseline), out_dir, footer, preset, baseline,
                                   build["commit"], student=student)
    files += figures.write_teacher_designs(results, out_dir, build, preset, student=student)
    _remove_stale(out_dir, [os.path.basename(p) for p in glob.glob(os.path.join(out_dir, "visitation_*.png"))])
    files += figures.write_visitation(results, out_dir, build,
                                      tasks if visitation_tasks is None else list(dict.fromkeys(visitation_tasks)),
                                      embedding, points_per_panel, baseline=baseline)
    manifest = {"build": build, "files": [os.path.relpath(p, out_dir) for p in files] + ["README.md"],
                "cells": [cells.cell_provenance(r) for r in results.values()],
                "not_run": [[t, m] for t in tasks for m in methods if (t, m) not in results],
                "grid_without_cells": {"tasks": [t for t in planned_tasks if t not in tasks],
                                       "methods": [m for m in planned_methods if m not in methods]},
                **({"aggregate_not_built": aggregate_note} if aggregate_note else {})}
    files.append(readme.write_readme(out_dir, manifest, rows, methods, footer, families))
    with open(os.path.join(out_dir, "manifest.json"), "w") as f:
        json.dump(manifest, f, indent=2, default=tables_md.json_default)
    return manifest


def _remove_stale(out_dir: str, names) -> None:
    """Removes the files ``names`` of an earlier build from ``out_dir``: only what this build writes stays."""
    for name in names:
        if os.path.exists(os.path.join(out_dir, name)):
            os.remove(os.path.join(out_dir, name))


def add_figure_options(p: argparse.ArgumentParser) -> None:
    """The state-visitation figure's options, shared by this module's CLI and experiments.reproduce."""
    p.add_argument("--embedding", default="tsne", choices=("tsne", "pca"),
                   help="2-D embedding of the state-visitation figure (pca is fast)")
    p.add_argument("--visitation-task", action="append", choices=grid.tasks(), default=None,
                   help="build the state-visitation figure for this task only (repeatable; default: every task "
                        "whose Meta (independent) and DDPG baseline cells stored their visited states)")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments.artefacts",
                                description="Rebuild Table 2 and the figures from stored run folders.")
    p.add_argument("--runs-dir", default="runs/reproduce", help="grid root: <runs-dir>/<preset>/<task>/<method>")
    p.add_argument("--results-dir", default="results", help="output folder (a non-paper preset goes to <dir>/<preset>)")
    p.add_argument("--preset", default="paper", choices=tuple(BASELINES))
    p.add_argument("--student", default="ddpg", choices=tuple(GRIDS),
                   help="whose grid the run folders hold: ddpg (default) or td3 (methods: experiments.grid.methods.GRIDS)")
    add_figure_options(p)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    manifest = build_all(args.runs_dir, args.results_dir, args.preset, embedding=args.embedding,
                         visitation_tasks=args.visitation_task, student=args.student)
    out = cells.results_dir_for(args.results_dir, args.preset)
    print(f"wrote {len(manifest['files'])} artefacts to {out} from {len(manifest['cells'])} stored cells")
    return 0


if __name__ == "__main__":
    sys.exit(main())
