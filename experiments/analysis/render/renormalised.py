"""A built benchmark's aggregate again under other normalisation anchors, into a folder of its own, from the
benchmark's per-task tables alone (``tasks/<task>.json``: each finished cell's per-seed final returns) and the
entries its manifest planned: the same IQM, mean and optimality gap with stratified bootstrap intervals,
probabilities of improvement over each student's baseline and best fixed noise, and performance profiles as the
benchmark's own aggregate (``experiments.analysis.benchmark.aggregate_report``), nothing else changed.

    python -m experiments.analysis.render.renormalised --results-dir results/exploration \\
        --anchors results/normalisation-dense.json --out results/exploration/dense-renormalised

(The dense benchmark normalised as the hard one is: 0 = the random policy, 1 = the task's own fixed reference,
``python -m experiments.normalisation --fixed-references``, rather than a baseline's score.)
Writes ``aggregate.md``, ``aggregate.json`` and ``performance_profiles.png`` into ``--out``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import sys


def task_rows(tables: dict[str, dict], entries, tasks) -> dict[str, list[dict]]:
    """{student: rows as ``experiments.analysis.benchmark.student_rows`` makes them} from the built task tables
    (``read_task_tables``), in the order of ``tasks`` (the plan's: the bootstrap resamples tasks in that order): per
    task and planned method its cell's status and per-seed final returns ("not run" where the table has none)."""
    rows = {task: {(r["student"], r["method"]): r for r in table["rows"]} for task, table in tables.items()}
    out = {}
    for student in dict.fromkeys(e.student for e in entries):
        methods = [e.method for e in entries if e.student == student]
        out[student] = [{"task": task, "methods": {m: rows.get(task, {}).get((student, m), {"status": "not run"})
                                                   for m in methods}} for task in tasks]
    return out


def main(argv: list[str] | None = None) -> int:
    from experiments import aggregate, normalisation
    from experiments.analysis.benchmark import Entry, aggregate_report, read_task_tables
    from metapg_jax.host.provenance import record

    p = argparse.ArgumentParser(prog="python -m experiments.analysis.render.renormalised", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--results-dir", required=True, help="a built benchmark (its manifest.json and tasks/*.json)")
    p.add_argument("--anchors", required=True, help="the normalisation anchors to score with")
    p.add_argument("--out", required=True, help="the folder of the new aggregate (not --results-dir itself)")
    a = p.parse_args(argv)
    manifest_path = os.path.join(a.results_dir, "manifest.json")
    try:
        tables = read_task_tables(a.results_dir)
        if not os.path.isfile(manifest_path) or not tables:
            raise ValueError(f"{a.results_dir}: not a built benchmark (no manifest.json or tasks/*.json)")
        if not os.path.isfile(a.anchors):
            raise ValueError(f"--anchors {a.anchors}: no such file")
        if os.path.abspath(a.out) == os.path.abspath(a.results_dir):
            raise ValueError("--out must be another folder than --results-dir (its own aggregate stays as built)")
        with open(manifest_path) as f:
            plan = json.load(f).get("benchmark")
        if not plan:
            raise ValueError(f"{manifest_path}: no benchmark plan")
        entries = [Entry(e["student"], e["method"], e["baseline"]) for e in plan["entries"]]
        anchors = normalisation.load(a.anchors)
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    tasks = list(plan["tasks"])
    rows = task_rows(tables, entries, tasks)
    rep, scored, why = aggregate_report(rows, entries, tasks, anchors)
    if rep is None:
        print(f"error: no aggregate: {why}", file=sys.stderr)
        return 2
    labels = rep.pop("labels")
    prov = record()
    rep["source"] = {"results_dir": aggregate.repo_path(a.results_dir),
                     "tables": "tasks/*.json (each finished cell's per-seed final returns)"}
    title = f"{plan['name']} benchmark, normalised with {os.path.basename(a.anchors)}"
    files = aggregate.write(rep, scored, a.out, title, {
        "date": datetime.date.today().isoformat(), "commit": prov.get("commit"), "dirty": prov.get("dirty"),
        "grid": f"{aggregate.repo_path(a.results_dir)}/tasks/*.json", "anchors": aggregate.repo_path(a.anchors)},
        labels=labels)
    print(f"wrote {', '.join(files)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
