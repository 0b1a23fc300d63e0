"""The tables of the artefacts, from stored cells (``experiments.analysis.cells``): the paper's Table 2
(``table2.md`` / ``.json`` / ``_per_seed.csv``), samples to reach the DDPG baseline's best
(``steps_to_threshold.csv`` / ``.md``) and every method against every other (``comparisons.md`` / ``.json``);
the paper's Table 2 numbers they are shown next to. What the explorers put in the buffer is
``experiments.analysis.behaviour``'s, the folder's ``README.md`` ``experiments.analysis.render.readme``'s.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from experiments.analysis.cells import cell_provenance
from experiments.grid.methods import (BASELINE, META, noise_methods)
from experiments.analysis.stats import (VerdictFamily, first_step_reaching, mean_std, num_final_evaluations,
                                        t_interval, welch_test)

# The seeds of the paper's Table 2 (Xu et al., 2018), whose numbers each task's spec holds (envs.TaskSpec.table2).
PAPER_SEEDS = 3


def paper_table2(task: str) -> dict | None:
    """The paper's Table 2 numbers for ``task`` (its spec's ``table2``): {'meta': (mean, std), 'ddpg': (mean, std)};
    None for a task the paper did not run."""
    import envs  # brax on import: only when a table is built

    row = envs.TASKS[task].table2 if task in envs.TASKS else None
    return None if row is None else {"meta": row.meta, "ddpg": row.ddpg}


# ---------------------------------------------------------------------------------------------- Table 2

def table2_rows(results: dict, tasks: Sequence[str], methods: Sequence[str], baseline: str = BASELINE) -> list[dict]:
    """One dict per task with, per method, the statistics of the finished runs (None: not run / incomplete)."""
    rows = []
    for task in tasks:
        row = {"task": task, "methods": {}, "paper": paper_table2(task)}
        for method in methods:
            r = results.get((task, method))
            if r is None:
                row["methods"][method] = {"status": "not run"}
                continue
            if not r.complete:
                row["methods"][method] = {"status": "incomplete", "env_steps_done": r.env_steps_done,
                                          "budget": r.budget}
                continue
            final = r.final()
            mean, std = mean_std(final)
            _, half = t_interval(final)
            row["methods"][method] = {
                "status": "done", "mean": mean, "std": std, "ci95_half_width": half,
                "ci95": [mean - half, mean + half] if math.isfinite(half) else None,
                "n": int(final.size), "budget": r.budget, "env_steps": r.env_steps_done,
                "final_evaluations": num_final_evaluations(r.steps.size), "evaluations": int(r.steps.size),
                "base_seed": r.run_args.get("seed"), "per_seed": [float(v) for v in final],
                "run_commit": r.provenance.get("commit"), "backend": r.info.get("backend"),
                "wall_seconds": cell_provenance(r)["wall_seconds"], "run_dir": r.path}
        a, b = row["methods"].get(META, {}), row["methods"].get(baseline, {})
        row["welch"] = None
        if a.get("status") == "done" and b.get("status") == "done":
            if a["budget"] == b["budget"]:  # never a test between cells of different budgets (mid-extension)
                t, p = welch_test(a["per_seed"], b["per_seed"])
                row["welch"] = {"t": t, "p": p, "difference": a["mean"] - b["mean"]}
            else:
                row["welch_skipped"] = "budgets differ"
        rows.append(row)
    return rows


def verdict_families(rows: list[dict], methods: Sequence[str], baseline: str,
                     anchors: dict[str, tuple[float, float]] | None = None) -> list[dict]:
    """The grid's corrected verdicts (``stats.judge_family``), one family per noise baseline: the grid's own
    ``baseline`` first (fixed in advance by the grid, ``experiments.grid.methods.baseline_for``), then every other noise
    baseline of ``methods``, so that no baseline is picked on the seeds it is judged on. A family holds every
    teacher (a method that does not explore with noise; every other method in a grid without one) against
    that baseline on every task where both cells finished at the same budget (cells of different budgets are
    listed as skipped). ``anchors`` (task -> (random, reference) returns) set each task's equivalence margin,
    ``EQUIVALENCE_MARGIN`` of the range; a task without anchors is never judged equivalent."""
    noise = noise_methods(methods)
    teachers = [m for m in methods if m not in noise]
    return [verdict_family(rows, base, [x for x in (teachers or methods) if x != base], anchors, base == baseline)
            for base in [baseline] + [m for m in noise if m != baseline]]


def verdict_family(rows: list[dict], base: str, compared_methods: Sequence[str],
                   anchors: dict[str, tuple[float, float]] | None = None, fixed_in_advance: bool = True) -> dict:
    """One family of corrected verdicts (``stats.judge_family``): each of ``compared_methods`` against ``base`` on
    every task of ``rows`` (``table2_rows``) where both cells finished at the same budget (cells of different
    budgets are listed as skipped); equivalence margins from ``anchors`` as in ``verdict_families``."""
    family, skipped = VerdictFamily(anchors), []
    for row in rows:
        b = row["methods"].get(base, {})
        for m in compared_methods:
            a = row["methods"].get(m, {})
            if a.get("status") != "done" or b.get("status") != "done":
                continue
            if a["budget"] != b["budget"]:  # never a test between cells of different budgets (mid-extension)
                skipped.append({"task": row["task"], "method": m, "why": "budgets differ"})
                continue
            family.add({"task": row["task"], "method": m}, a["per_seed"], b["per_seed"], row["task"])
    return {"baseline": base, "fixed_in_advance": fixed_in_advance, "skipped": skipped,
            "comparisons": [{**c, **j} for c, j in family.judge()]}


# ---------------------------------------------------------------------------------------------- steps to threshold

def steps_to_threshold_rows(results: dict, tasks: Sequence[str], methods: Sequence[str],
                            baseline: str = BASELINE) -> list[dict]:
    """Per task and method: first env step where the seed-mean curve reaches the DDPG baseline's best seed mean."""
    rows = []
    for task in tasks:
        base = results.get((task, baseline))
        if base is None:
            continue
        base_mean = np.nanmean(base.values, 0)
        threshold = float(np.nanmax(base_mean))
        base_step = first_step_reaching(base.steps, base_mean, threshold)
        for m in methods:
            r = results.get((task, m))
            if r is None:
                continue
            step = first_step_reaching(r.steps, np.nanmean(r.values, 0), threshold)
            rows.append({"task": task, "method": m, "threshold": threshold, "baseline_step": base_step,
                         "step": step, "ratio": (step / base_step) if step is not None and base_step else None,
                         "seeds": r.num_seeds, "env_steps_run": r.env_steps_done, "complete": r.complete,
                         "baseline_complete": base.complete})
    return rows


# ---------------------------------------------------------------------------------------------- comparisons

def comparison_rows(results: dict, tasks: Sequence[str], methods: Sequence[str]) -> dict:
    """Every method against every other, per task: the numbers docs/results.md quotes.

    ``{"methods": [...], "pairs": [...]}``. Per finished cell: median, min and max of the seeds' final
    returns, the best value of the seed-mean curve and its step, the mean of the seed-mean curve over all
    evaluations. Per pair (a, b) of finished cells with the same budget (in ``methods`` order): the
    difference of mean finals a − b, Welch's t and p, and at how many of their common evaluation steps the
    seed-mean curve of a is above b's, and b's above a's."""
    per_method, pairs = [], []
    for task in tasks:
        done = [m for m in methods if (task, m) in results and results[(task, m)].complete]
        finals = {m: results[(task, m)].final() for m in done}
        curves = {m: np.nanmean(results[(task, m)].values, 0) for m in done}  # seed-mean curves
        for m in done:
            r, final, curve = results[(task, m)], finals[m], curves[m]
            best = int(np.nanargmax(curve))
            per_method.append({"task": task, "method": m, "n": int(final.size), "budget": r.budget,
                               "mean": float(final.mean()), "median": float(np.median(final)),
                               "min": float(final.min()), "max": float(final.max()),
                               "best_seed_mean": float(curve[best]), "best_seed_mean_step": int(r.steps[best]),
                               "mean_over_evaluations": float(np.nanmean(curve)), "evaluations": int(r.steps.size)})
        for i, a in enumerate(done):
            for b in done[i + 1:]:
                ra, rb = results[(task, a)], results[(task, b)]
                if ra.budget != rb.budget:
                    continue  # mid-extension: never compared across budgets (as table2_rows)
                t, p = welch_test(finals[a], finals[b])
                common, ia, ib = np.intersect1d(ra.steps, rb.steps, return_indices=True)
                ca, cb = curves[a][ia], curves[b][ib]
                pairs.append({"task": task, "a": a, "b": b, "budget": ra.budget,
                              "difference": float(finals[a].mean() - finals[b].mean()), "t": t, "p": p,
                              "a_above_b": int((ca > cb).sum()), "b_above_a": int((cb > ca).sum()),
                              "common_evaluations": int(common.size)})
    return {"methods": per_method, "pairs": pairs}


# ---------------------------------------------------------------------------------------------- behaviour
