"""Diagnostics of the learned-exploration variants and controls (results/learned/README.md): what each hypothesis
predicts, measured from the archived per-cycle metrics (``cells.ARCHIVE_CYCLES``) of a benchmark's finished cells.

    python -m experiments.analysis.learned --results-dir results/learned/screen --tasks hopper,halfcheetah
    python -m experiments.analysis.learned --results-dir results/learned/judgement --students td3,sac --goal

Per (student, task, method) of ``grid.LEARNED_METHODS`` with a finished archived cell, over each seed's last
``LAST`` cycles (all of them if it has fewer), pooled over seeds unless said otherwise:

* the meta reward's noise (H3): the root mean square over cycles of its spread over the eval envs, paired
  (``meta_reward_sd_paired``, the per-env differences of R_hat(pi') and R_hat(pi) from the same resets) and
  unpaired (``meta_reward_sd_unpaired``, what the difference of independent rollouts would spread), and their
  ratio (of RMS spreads, i.e. the square root of the ratio of mean variances: each cycle's variances are
  unbiased, so a pairing that changes nothing gives about 1, where a ratio of median spreads over two envs
  would lean toward pairing); the meta reward's mean and standard deviation over cycles, and |mean| / std; the
  standard deviation over seeds of each seed's mean meta reward (what separates two cells' means: cycles of one
  seed are not independent draws);
* D0's distance from the student (H1): the RMS teacher-student action distance on D0 (noise included), mean ±
  std over seeds of each seed's mean; and the same for the teacher's mean alone (``teacher_mean_distance``, its
  noise left out: how far what it learned moves it; not measured in cells made before that metric existed);
* the bandit's choice (H2, ``--teacher=bandit`` with two or more scales): per seed the arm chosen most often and
  its share of the cycles; the seeds whose favourite has more than half; the favourite scales' counts.

Then each hypothesis' predictions, fixed before the screen ran (results/learned/README.md), checked per task
(``predictions``):

* comparisons of final returns (``COMPARISONS``): each variant against the cell its hypothesis names, one family
  over every comparison and task, Welch tests Holm-corrected within it, 'equivalent' only by the TOST of
  ``stats.EQUIVALENCE_MARGIN`` of the task's normalisation range (``stats.judge_family``, as every grid's
  verdicts). A prediction that a variant *beats* its reference is met by 'better' and refuted by 'worse' or
  'equivalent'; one that it is *not worse* is met by 'better' or 'equivalent' and refuted by 'worse'; else it is
  inconclusive. A comparison whose reference is not one of the student's strategies (the tuned teacher for SAC)
  is left out;
* thresholds on the diagnostics (``DIAGNOSTIC_PREDICTIONS``): met, not met, or not measured (the cell has no
  such metric);
* what each variant adds over each control (H4): every variant against every control on every task, except the
  pairs ``COMPARISONS`` already judges, a second family corrected within itself.

Where the folder holds the benchmark's ``manifest.json``, only what its plan holds is read: a cell, prediction or
comparison that names a strategy the grid never planned (the screen's controls in the judgement) is left out, not
listed as not run.

With ``--goal`` (the judgement on fresh seeds, results/learned/README.md), read from the artefacts that
``python -m experiments.benchmark ... --artefacts-only`` last wrote into the folder: per student, each variant's
probability of improvement over the student's baseline (the grid's ``--baseline``: the best fixed strategy chosen
in advance) with its 95% stratified bootstrap CI (``aggregate.json``), and its verdicts against that baseline
(``tasks/<task>.json``; Holm-corrected over the student's family: every one of its strategies on every task). The
goal (``GOAL``) is met when the CI's lower bound is above 0.5 and no task is worse, not met otherwise, and pending,
with the reason, while the build that wrote those files had a planned cell of the student not finished (the
family, and so every verdict, grows with it) or left a task out of the aggregate. The tasks are the grid's.

Writes ``<results-dir>/diagnostics.md`` and ``diagnostics.json``. A cell that is not finished, or whose cycles are
not archived, is listed as such: nothing is estimated.
"""

from __future__ import annotations

import gzip
import json
import math
import os
import sys
from collections import Counter

import numpy as np

from experiments.analysis import stats
from experiments.analysis.cells import ARCHIVE_CYCLES, build_info, load_run, read_json
from experiments.grid.methods import LEARNED, STRATEGIES, task_folder

LAST = 100  # cycles per seed at the end of training that the diagnostics read
VARIANTS = ("learned-paired", "learned-residual", "learned-bandit")
CONTROLS = ("control-frozen", "control-uniform", "control-fixed", "control-pink", "control-noiseless")
# The hypotheses' predictions about final returns (results/learned/README.md): (hypothesis, variant, reference,
# "beats" or "not worse"), each on every task; one family.
COMPARISONS = (
    ("H1", "learned-residual", "meta-tuned", "not worse"),
    ("H1", "learned-residual", "control-fixed", "not worse"),
    ("H2", "learned-bandit", "control-fixed", "beats"),
    ("H3", "learned-paired", "control-frozen", "beats"),
)
# ... and about the diagnostics: (hypothesis, method, what is predicted, the measured value from its
# cell_diagnostics (None: not measured), the prediction as a test of that value).
DIAGNOSTIC_PREDICTIONS = (
    ("H1", "learned-residual", "D0's RMS distance from the student at most 0.3 (the independent teacher's: "
     "about 1.0)", lambda d: d["distance_mean"], lambda v: v <= 0.3),
    ("H2", "learned-bandit", "one arm in more than half of the last cycles on more than half of the seeds "
     "(measured: the fraction of such seeds)",
     lambda d: d["bandit"]["seeds_over_half"] / d["seeds"] if "bandit" in d else None, lambda v: v > 0.5),
    ("H3", "learned-paired", "paired / unpaired RMS spread of the meta reward at most 0.5",
     lambda d: d["sd_ratio"], lambda v: v <= 0.5),
)


GOAL = ("P(variant > baseline, the best fixed strategy chosen in advance) with its 95% CI's lower bound above 0.5, "
        "and no task significantly worse after correction")
ARTEFACTS_FIRST = "python -m experiments.benchmark ... --artefacts-only"


def load_plan(results_dir: str) -> dict | None:
    """The benchmark's plan (``manifest.json``'s ``benchmark``, with its ``not_run`` and ``unfinished`` cells) of
    the grid in ``results_dir``; None where the folder holds no benchmark's manifest."""
    manifest = read_json(os.path.join(results_dir, "manifest.json"))
    if "benchmark" not in manifest:
        return None
    return {**manifest["benchmark"], "not_run": manifest.get("not_run", []),
            "unfinished": manifest.get("unfinished", [])}


def planned(plan: dict | None) -> dict[str, set[str]] | None:
    """{student: the methods the grid planned} of a ``load_plan``; None without one."""
    if plan is None:
        return None
    out: dict[str, set[str]] = {}
    for e in plan.get("entries", []):
        out.setdefault(e["student"], set()).add(e["method"])
    return out


def read_cycles(path: str) -> dict[int, list[dict]]:
    """{seed: its cycles' rows in cycle order} from a cell's ``cycles.jsonl.gz``."""
    seeds: dict[int, list[dict]] = {}
    with gzip.open(path, "rt") as f:
        for line in f:
            row = json.loads(line)
            seeds.setdefault(int(row["seed"]), []).append(row)
    return {s: sorted(rows, key=lambda r: r["cycle"]) for s, rows in sorted(seeds.items())}


def _finite(values) -> np.ndarray:
    x = np.asarray([v for v in values if v is not None], np.float64)
    return x[np.isfinite(x)]


def _rms(values) -> float | None:
    x = _finite(values)
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else None


def cell_diagnostics(cell_dir: str, last: int = LAST) -> dict:
    """The diagnostics of one archived cell (module docstring); ``{"state": ...}`` only when it cannot have any."""
    if not os.path.exists(os.path.join(cell_dir, "summary.json")):
        return {"state": "not run"}
    cycles_path = os.path.join(cell_dir, ARCHIVE_CYCLES)
    if not os.path.exists(cycles_path):
        return {"state": "no per-cycle metrics archived"}
    with open(os.path.join(cell_dir, "config.json")) as f:
        config = json.load(f)["config"]
    tail = {s: rows[-last:] for s, rows in read_cycles(cycles_path).items()}
    rows = [r for rs in tail.values() for r in rs]
    per_seed = [_finite(r["meta_reward"] for r in rs) for rs in tail.values()]
    reward = np.concatenate(per_seed)
    seed_means = [float(np.mean(x)) for x in per_seed if x.size]
    paired = _rms(r.get("meta_reward_sd_paired") for r in rows)
    unpaired = _rms(r.get("meta_reward_sd_unpaired") for r in rows)
    distance = [float(np.mean(_finite(r["teacher_student_distance"] for r in rs))) for rs in tail.values()]
    offsets = [_finite(r.get("teacher_mean_distance") for r in rs) for rs in tail.values()]
    offset = [float(np.mean(x)) for x in offsets if x.size]
    out = {"state": "finished", "seeds": len(tail), "cycles_per_seed": min(len(rs) for rs in tail.values()),
           "sd_paired_rms": paired, "sd_unpaired_rms": unpaired,
           "sd_ratio": paired / unpaired if paired is not None and unpaired else None,
           "meta_reward_mean": float(np.mean(reward)) if reward.size else None,
           "meta_reward_std": float(np.std(reward, ddof=1)) if reward.size > 1 else None,
           "meta_reward_seed_std": float(np.std(seed_means, ddof=1)) if len(seed_means) > 1 else None,
           "distance_mean": float(np.mean(distance)), "distance_std": float(np.std(distance, ddof=1))
           if len(distance) > 1 else None,
           "mean_distance_mean": float(np.mean(offset)) if offset else None,
           "mean_distance_std": float(np.std(offset, ddof=1)) if len(offset) > 1 else None}
    m, s = out["meta_reward_mean"], out["meta_reward_std"]
    out["meta_reward_snr"] = abs(m) / s if m is not None and s else None
    meta = config.get("meta", {})
    scales = config.get("bandit", {}).get("scales", [])
    if meta.get("teacher") == "bandit" and len(scales) > 1:
        logs = np.log(np.maximum(np.asarray(scales, np.float64), 1e-6))
        favourites = []
        for rs in tail.values():
            arms = [int(np.argmin(np.abs(logs - r["teacher_log_std"]))) for r in rs
                    if r.get("teacher_log_std") is not None]
            arm, n = Counter(arms).most_common(1)[0]
            favourites.append({"scale": float(scales[arm]), "share": n / len(rs)})
        out["bandit"] = {"scales": [float(x) for x in scales], "favourites": favourites,
                         "seeds_over_half": sum(f["share"] > 0.5 for f in favourites),
                         "favourite_counts": {f"{k:g}": v for k, v in
                                              sorted(Counter(f["scale"] for f in favourites).items())}}
    return out


def final_returns(results_dir: str, student: str, task: str, method: str) -> tuple[list[float], int] | None:
    """(per-seed final returns, budget) of an archived finished cell (``stats.final_returns``), else None."""
    r = load_run(os.path.join(results_dir, student, "cells", task_folder(task), method), task, method)
    return None if r is None or not r.complete else ([float(v) for v in r.final()], r.budget)


def outcome(kind: str, verdict: str) -> str:
    """A comparison's prediction ("beats" or "not worse") given its corrected verdict: met, refuted or
    inconclusive."""
    if kind == "beats":
        return "met" if verdict == "better" else "refuted" if verdict in ("worse", "equivalent") else "inconclusive"
    return "met" if verdict in ("better", "equivalent") else "refuted" if verdict == "worse" else "inconclusive"


def judged(results_dir: str, student: str, tasks: list[str], pairs: list[tuple[str, str]],
           anchors: dict | None) -> list[dict]:
    """One family: each (a, b) of ``pairs`` on each task, Holm-corrected over those where both cells finished at
    the same budget (``stats.VerdictFamily``); the others with their state."""
    rows, family = [], stats.VerdictFamily(anchors)
    for a, b in pairs:
        for task in tasks:
            fa, fb = final_returns(results_dir, student, task, a), final_returns(results_dir, student, task, b)
            row = {"task": task, "a": a, "b": b}
            if fa is None or fb is None:
                rows.append({**row, "state": "not run: " + ", ".join(m for m, f in ((a, fa), (b, fb)) if f is None)})
            elif fa[1] != fb[1]:
                rows.append({**row, "state": "budgets differ"})
            else:
                rows.append({**row, "state": "compared", "mean_a": float(np.mean(fa[0])),
                             "mean_b": float(np.mean(fb[0]))})
                family.add(len(rows) - 1, fa[0], fb[0], task)
    for i, verdict in family.judge():
        rows[i].update(verdict)
    return rows


def predictions(results_dir: str, student: str, tasks: list[str], cells: list[dict], anchors: dict | None,
                plan: set[str] | None = None) -> dict:
    """The hypotheses' predictions on ``tasks`` (module docstring): {"comparisons": [...], "diagnostics": [...],
    "controls": [...]}; ``plan``: the student's planned methods (``planned``), None for every strategy of it."""
    own = [m for m in (*STRATEGIES.get(student, ()), *LEARNED.get(student, ())) if plan is None or m in plan]
    mine = [c for c in COMPARISONS if c[1] in own and c[2] in own]
    comparisons = judged(results_dir, student, tasks, [(a, b) for _, a, b, _ in mine], anchors)
    kinds = {(a, b): (h, kind) for h, a, b, kind in mine}
    for row in comparisons:
        h, kind = kinds[(row["a"], row["b"])]
        row.update(hypothesis=h, prediction=kind,
                   outcome=outcome(kind, row["verdict"]) if row["state"] == "compared" else row["state"])
    by_cell = {(c["task"], c["method"]): c for c in cells if c["student"] == student}
    diagnostics = []
    for h, method, what, value, test in DIAGNOSTIC_PREDICTIONS:
        if method not in own:
            continue
        for task in tasks:
            d = by_cell.get((task, method), {"state": "not run"})
            v = value(d) if d["state"] == "finished" else None
            v = None if v is None or not math.isfinite(v) else float(v)
            diagnostics.append({"hypothesis": h, "method": method, "task": task, "prediction": what, "value": v,
                                "outcome": d["state"] if d["state"] != "finished" else "not measured" if v is None
                                else "met" if test(v) else "not met"})
    judged_pairs = {(a, b) for _, a, b, _ in mine}
    controls = judged(results_dir, student, tasks, [(v, c) for v in VARIANTS for c in CONTROLS
                                                    if v in own and c in own and (v, c) not in judged_pairs], anchors)
    return {"comparisons": comparisons, "diagnostics": diagnostics, "controls": controls}


def goal(results_dir: str, plan: dict, students: list[str]) -> dict:
    """The judgement's goal (module docstring) from the benchmark's artefacts in ``results_dir`` and its ``plan``
    (``load_plan``): {student: {"baseline": method, "variants": [{method, p, lo, hi, per_task: {task: P}, verdicts:
    {task: verdict}, worse, better, outcome}]}}. ``ValueError`` (one line) for artefacts that are not there."""
    tasks = list(plan["tasks"])
    agg_path = os.path.join(results_dir, "aggregate.json")
    if not os.path.exists(agg_path):
        raise ValueError(f"--goal: no aggregate.json in {results_dir} (build the grid's artefacts first: "
                         f"{ARTEFACTS_FIRST}; the aggregate needs every task's normalisation anchors)")
    with open(agg_path) as f:
        agg = json.load(f)
    verdicts: dict[tuple[str, str, str], str] = {}
    for task in tasks:
        path = os.path.join(results_dir, "tasks", f"{task_folder(task)}.json")
        if not os.path.exists(path):
            raise ValueError(f"--goal: no tasks/{task_folder(task)}.json in {results_dir} ({ARTEFACTS_FIRST})")
        with open(path) as f:
            for r in json.load(f)["rows"]:
                if r.get("verdict"):
                    verdicts[(r["student"], task, r["method"])] = r["verdict"]["verdict"]
    methods = planned(plan)
    out = {}
    for student in students:
        base = plan["baselines"][student]
        open_cells = [f"{t}/{m} " + ("not run" if [s, t, m] in plan["not_run"] else "unfinished")
                      for s, t, m in plan["not_run"] + plan["unfinished"] if s == student]
        left_out = [t for t in tasks if t not in agg.get("tasks", [])]
        n_cells = len(tasks) * len(methods[student])
        rows = []
        for method in VARIANTS:
            if method not in methods[student] or method == base:
                continue
            p = next((r for r in agg.get("improvement", []) if r["x"] == f"{student}/{method}"
                      and r.get("reference") == "baseline"), None)
            v = {t: verdicts.get((student, t, method)) for t in tasks}
            row = {"method": method, "verdicts": v, "worse": [t for t in tasks if v[t] == "worse"],
                   "better": [t for t in tasks if v[t] == "better"],
                   **({"p": p["point"], "lo": p["lo"], "hi": p["hi"],
                       "per_task": dict(zip(agg["tasks"], p.get("per_task") or []))} if p else {})}
            why = ([f"{len(open_cells)} of the student's {n_cells} planned cells not finished: "
                    + ", ".join(open_cells[:3]) + (", ..." if len(open_cells) > 3 else "")] if open_cells else []) + \
                  ([f"not in the aggregate: {', '.join(left_out)}"] if left_out else []) + \
                  ([f"no verdict on {', '.join(t for t in tasks if v[t] is None)}"] if None in v.values() else []) + \
                  (["no probability of improvement"] if p is None else [])
            row["outcome"] = ("pending (" + "; ".join(why) + ")" if why
                              else "met" if p["lo"] > 0.5 and not row["worse"] else "not met")
            rows.append(row)
        out[student] = {"baseline": base, "variants": rows}
    return out


def build(results_dir: str, tasks: list[str], students: list[str], last: int = LAST,
          anchors: dict | None = None, plan: dict | None = None) -> dict:
    """{"cells": [{student, task, method, **cell_diagnostics}], "predictions": {student: ``predictions``},
    "last": last, "built": provenance}; ``anchors``: the tasks' normalisation anchors (equivalence margins);
    ``plan``: the grid's (``load_plan``), whose methods alone are read."""
    methods = planned(plan)
    mine = {s: None if methods is None else methods[s] for s in students}
    cells = []
    for student in students:
        for task in tasks:
            for method in LEARNED[student]:
                if mine[student] is not None and method not in mine[student]:
                    continue
                d = os.path.join(results_dir, student, "cells", task_folder(task), method)
                cells.append({"student": student, "task": task, "method": method, **cell_diagnostics(d, last)})
    return {"last": last, "cells": cells, "built": build_info(results_dir),
            "predictions": {s: predictions(results_dir, s, tasks, cells, anchors, mine[s]) for s in students}}


if __name__ == "__main__":  # the command's parsing and files are the rendering side's
    from experiments.analysis.render.learned import main

    sys.exit(main())
