"""The signal check of a meta reward, before any teacher learns from it: only a reward that passes goes on to one.

Each reward variant is one benchmark grid (a folder of its own) whose entries are fixed-D0 controls of the shared
cycle (``D0S``: nothing in D0 learns); the variant is the cycle's ``meta.baseline`` / ``meta.lookahead_data``,
the same for every cell of the grid. Per variant and task, from each D0 cell's archived per-cycle metrics
(``cells.ARCHIVE_CYCLES``) and final returns:

* the reward a D0 earns: per seed, the mean meta reward over all of its cycles (what a teacher would climb);
* what the D0 does to the student: per seed, its final return (``stats.final_returns``);
* **rank agreement**: Spearman's rho over the D0s between their mean (over seeds) meta reward and their mean final
  return, with a 95% percentile interval from ``REPS`` bootstrap resamples of the seeds, drawn within each cell
  independently (a resample whose meta rewards or returns are all tied has no ranking: rho 0);
* **separation**: the best-minus-worst gap of the D0s' mean meta rewards over the seeds' pooled standard
  deviation (the root mean of the cells' variances over seeds of the seed means);
* **effect**: whether the task has a difference between D0s to rank: the Kruskal-Wallis test of the D0s' final
  returns (p 1 where every return is the same).

The pass rule (``PASS_RULE``, fixed before the grids ran): on a task, a variant passes when the rank agreement's
interval lies above 0 and the separation ratio is above 1; a task whose effect p is 0.05 or more has nothing to
rank and counts as not passed. A variant goes on to a learner (a bandit over D0s first, then a teacher) when it
passes on at least ``PASS_TASKS`` of the tasks; if none does, that is the result.

    python -m experiments.analysis.signal --results-dir results/learned/signal \
        --variants paired,counterfactual-d0,counterfactual-mix --tasks <the grids' tasks>

Writes ``<results-dir>/signal.md`` and ``signal.json``. A cell that is not finished or has no archived cycles is
listed as such, and its task is not judged for that variant.
"""

from __future__ import annotations

import os

import numpy as np
from scipy import stats as scipy_stats

from experiments.analysis.cells import ARCHIVE_CYCLES
from experiments.analysis.learned import final_returns, read_cycles
from experiments.grid.methods import task_folder

# The fixed D0s of the shared cycle, in the order the tables list them (experiments.grid.methods: uniformly random
# actions, the student with Gaussian or pink noise 0.1, the student alone).
D0S = ("control-uniform", "control-fixed", "control-pink", "control-noiseless")
STUDENT = "td3"
REPS = 2_000
SEED = 0
LEVEL = 0.95
PASS_TASKS = 3
EFFECT_ALPHA = 0.05
PASS_RULE = ("on a task: the D0s' final returns differ (Kruskal-Wallis p below 0.05), Spearman's rho between the "
             "D0s' mean meta reward and mean final return has its 95% seed-bootstrap interval above 0, and the D0s' "
             "mean meta rewards differ (best-minus-worst gap above the seeds' pooled std); a variant goes on when it "
             f"passes on at least {PASS_TASKS} tasks")


def seed_rewards(cell_dir: str) -> np.ndarray | None:
    """Each seed's mean meta reward over its cycles (seed order), or None where no cycles are archived."""
    path = os.path.join(cell_dir, ARCHIVE_CYCLES)
    if not os.path.exists(path):
        return None
    out = []
    for rows in read_cycles(path).values():
        x = np.asarray([r["meta_reward"] for r in rows if r.get("meta_reward") is not None], np.float64)
        x = x[np.isfinite(x)]
        out.append(float(np.mean(x)) if x.size else np.nan)
    return np.asarray(out, np.float64)


def _pooled_std(groups: list[np.ndarray]) -> float:
    return float(np.sqrt(np.mean([np.var(g, ddof=1) for g in groups])))


def _gap_ratio(groups: list[np.ndarray]) -> float:
    means = [float(np.mean(g)) for g in groups]
    sd = _pooled_std(groups)
    gap = max(means) - min(means)
    return float(gap / sd) if sd > 0 else (float("inf") if gap > 0 else 0.0)


def effect_p(returns: list[np.ndarray]) -> float:
    """The Kruskal-Wallis p-value of the D0s' final returns; 1 where all of them are the same value."""
    if np.ptp(np.concatenate(returns)) == 0:
        return 1.0
    return float(scipy_stats.kruskal(*returns).pvalue)


def _rho(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Spearman's rho (ties: average ranks) of each row of ``x`` with the same row of ``y`` (last axis: the D0s);
    0 where either row is all tied (no ranking). Rounded to 12 digits: exact ranks give exact values."""
    rx, ry = (scipy_stats.rankdata(v, axis=-1) for v in (x, y))
    rx, ry = rx - rx.mean(-1, keepdims=True), ry - ry.mean(-1, keepdims=True)
    norm = np.sqrt(np.sum(rx * rx, -1) * np.sum(ry * ry, -1))
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = np.where(norm > 0, np.sum(rx * ry, -1) / np.where(norm > 0, norm, 1.0), 0.0)
    return np.round(rho, 12)


def rank_agreement(rewards: list[np.ndarray], returns: list[np.ndarray], reps: int = REPS, seed: int = SEED,
                   level: float = LEVEL) -> dict:
    """Spearman's rho over the D0s (one array of per-seed values each) between mean reward and mean return, and its
    bootstrap interval (seeds resampled within each D0's cell; a seed's reward and return stay together)."""
    rho = float(_rho(np.array([np.mean(r) for r in rewards]), np.array([np.mean(r) for r in returns])))
    rng = np.random.default_rng(seed)
    idx = [rng.integers(0, len(r), (reps, len(r))) for r in rewards]
    mean_rewards = np.stack([r[i].mean(1) for r, i in zip(rewards, idx)], -1)
    mean_returns = np.stack([g[i].mean(1) for g, i in zip(returns, idx)], -1)
    lo, hi = np.percentile(_rho(mean_rewards, mean_returns), [50 * (1 - level), 50 * (1 + level)])
    return {"rho": rho, "rho_lo": float(lo), "rho_hi": float(hi)}


def judge_task(rewards: list[np.ndarray], returns: list[np.ndarray], reps: int = REPS) -> dict:
    """The pass rule on one task of one variant (module docstring)."""
    out = {**rank_agreement(rewards, returns, reps), "separation": _gap_ratio(rewards), "effect_p": effect_p(returns)}
    if out["effect_p"] >= EFFECT_ALPHA:
        out["outcome"] = "no effect to rank"
    else:
        out["outcome"] = "passed" if out["rho_lo"] > 0 and out["separation"] > 1 else "not passed"
    return out


def cell(results_dir: str, task: str, d0: str) -> dict:
    """One D0 cell of a variant's grid: its per-seed mean meta rewards and final returns, or its state."""
    cell_dir = os.path.join(results_dir, STUDENT, "cells", task_folder(task), d0)
    finals = final_returns(results_dir, STUDENT, task, d0)
    if finals is None:
        return {"state": "not run"}
    rewards = seed_rewards(cell_dir)
    if rewards is None:
        return {"state": "no per-cycle metrics archived"}
    returns = np.asarray(finals[0], np.float64)
    if len(rewards) != len(returns) or len(returns) < 2 or not np.all(np.isfinite(rewards)):
        return {"state": "seeds without a meta reward or fewer than 2 seeds"}
    return {"state": "finished", "budget": finals[1], "rewards": rewards, "returns": returns}


def check(results_dir: str, variants: list[str], tasks: list[str], reps: int = REPS) -> dict:
    """{"variants": [{variant, tasks: [{task, cells: {d0: summary}, **judge_task or state}], passed, outcome}]} of
    the variants' grids (``<results_dir>/<variant>``) on ``tasks``."""
    out = []
    for variant in variants:
        rows = []
        for task in tasks:
            cells = {d0: cell(os.path.join(results_dir, variant), task, d0) for d0 in D0S}
            summary = {d0: ({"state": c["state"]} if c["state"] != "finished" else {
                "state": "finished", "seeds": len(c["returns"]), "budget": c["budget"],
                "reward_mean": float(np.mean(c["rewards"])), "reward_seed_std": float(np.std(c["rewards"], ddof=1)),
                "return_mean": float(np.mean(c["returns"])), "return_std": float(np.std(c["returns"], ddof=1)),
                "rewards": c["rewards"].tolist(), "returns": c["returns"].tolist()}) for d0, c in cells.items()}
            row = {"task": task, "cells": summary}
            missing = [d0 for d0, c in cells.items() if c["state"] != "finished"]
            if missing:
                row["outcome"] = "not judged: " + ", ".join(f"{d0} {cells[d0]['state']}" for d0 in missing)
            elif len({c["budget"] for c in cells.values()}) > 1:
                row["outcome"] = "not judged: budgets differ"
            else:
                row.update(judge_task([c["rewards"] for c in cells.values()], [c["returns"] for c in cells.values()],
                                      reps))
            rows.append(row)
        passed = sum(r["outcome"] == "passed" for r in rows)
        pending = any(r["outcome"].startswith("not judged") for r in rows)
        open_tasks = sum(r["outcome"].startswith("not judged") for r in rows)
        verdict = ("goes on" if passed >= PASS_TASKS else
                   "pending" if pending and passed + open_tasks >= PASS_TASKS else "stops")
        out.append({"variant": variant, "tasks": rows, "passed": passed, "outcome": verdict})
    return {"pass_rule": PASS_RULE, "d0s": list(D0S), "student": STUDENT, "reps": reps, "variants": out}


if __name__ == "__main__":  # the command's parsing and files are the rendering side's
    import sys

    from experiments.analysis.render.signal import main

    sys.exit(main())
