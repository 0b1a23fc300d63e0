"""How many seeds a study's comparisons need, and how much a task's outcome depends on its exploration.

A study judges each entry against its baseline per task with Welch tests, Holm-corrected over the family of its
``comparisons`` (``experiments.analysis.stats.judge_family``). The comparison that Holm holds to the strictest level
is the first, at alpha / comparisons; the rule here asks that it, too, has the power to detect the difference that
matters, so that no verdict of the family is starved of seeds:

* ``power``: the power of a two-sided two-sample t test of ``n`` seeds per cell at level ``alpha / comparisons``
  for a true difference of ``effect`` seed standard deviations (equal seeds and spread in both cells: the
  noncentral t distribution with 2(n - 1) degrees of freedom, which Welch's test has for equal n and variance).
* ``detectable_effect``: the smallest such difference, in seed standard deviations, that ``n`` seeds detect with
  the asked power (e.g. 10 seeds, 80%: 1.32 std uncorrected, 2.11 std at level 0.05 / 36).
* ``seeds_for``: the study's seed rule. The fewest seeds (at least ``minimum``) at which a difference of ``delta``
  (in return units: a declared fraction of the task's range) is detected with that power, given a pilot's seed
  standard deviation ``std``.
* ``exploration_matters``: per task, the spread between the best and the worst entry's mean final return over
  the seeds' pooled standard deviation: a task where no entry stands out from the seed noise (a small figure)
  cannot tell strategies apart whatever the seed count.
* ``seed_plan``: the rule applied to a pilot grid's final returns, task by task: the seeds' standard deviation
  pooled over the pilot's entries, the difference that matters as a ``fraction`` of the task's normalised range
  (reference - random policy, ``experiments.normalisation``), and ``seeds_for``'s count, capped at ``maximum``
  (a cost cap: where the rule asks for more, the plan says so and what the capped count detects).

``python -m experiments.analysis.power --results-dir <a pilot benchmark's results> --anchors <file>`` writes the
plan (``seeds.md``, ``seeds.json``; ``experiments.analysis.render.power``).
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

POWER = 0.8
ALPHA = 0.05


def _check(n: int, comparisons: int, power: float, alpha: float) -> None:
    if int(n) != n or n < 2:
        raise ValueError(f"seeds per cell must be a whole number >= 2, got {n!r}")
    if int(comparisons) != comparisons or comparisons < 1:
        raise ValueError(f"comparisons must be a whole number >= 1, got {comparisons!r}")
    if not 0 < power < 1 or not 0 < alpha < 1:
        raise ValueError(f"power and alpha must lie in (0, 1), got {power!r} and {alpha!r}")


def power(n: int, effect: float, comparisons: int = 1, alpha: float = ALPHA) -> float:
    """The power of the two-sided two-sample t test (``n`` seeds per cell, level ``alpha / comparisons``) for a true
    difference of ``effect`` seed standard deviations."""
    from scipy import integrate, stats

    _check(n, comparisons, 0.5, alpha)
    df = 2 * (n - 1)
    crit = stats.t.ppf(1 - alpha / comparisons / 2, df)
    shift = abs(effect) / math.sqrt(2.0 / n)
    # P(|Z + shift| > crit * S), S = sqrt(V / df), V ~ chi2(df): the noncentral t's two tails, integrated over V
    # (scipy's nct returns NaN far out in the tail, where the power is near 1).
    chi2 = stats.chi2(df)

    def tails(v: float) -> float:
        s = crit * math.sqrt(v / df)
        return (stats.norm.sf(s - shift) + stats.norm.cdf(-s - shift)) * chi2.pdf(v)

    low, high = chi2.ppf(1e-14), chi2.isf(1e-14)  # where V's mass is (quad over [0, inf) misses it for large df)
    return float(min(1.0, integrate.quad(tails, low, high, epsabs=1e-13, limit=200)[0]))


def detectable_effect(n: int, comparisons: int = 1, power_: float = POWER, alpha: float = ALPHA) -> float:
    """The smallest difference, in seed standard deviations, that ``n`` seeds per cell detect with power ``power_``
    at level ``alpha / comparisons`` (two-sided)."""
    from scipy import optimize

    _check(n, comparisons, power_, alpha)
    high = 0.5
    while not power(n, high, comparisons, alpha) >= power_:  # the power grows with the difference
        high *= 2
        if high > 64:
            raise ValueError(f"{n} seeds do not reach a power of {power_:g} at level {alpha:g}/{comparisons}")
    return float(optimize.brentq(lambda d: power(n, d, comparisons, alpha) - power_, 0.0, high, xtol=1e-10))


def seeds_for(std: float, delta: float, comparisons: int = 1, power_: float = POWER, alpha: float = ALPHA,
              minimum: int = 10, maximum: int = 1000) -> int:
    """The fewest seeds per cell, at least ``minimum``, whose test at level ``alpha / comparisons`` detects a
    difference of ``delta`` (return units) with power ``power_`` when the seeds' standard deviation is ``std``.
    ``ValueError`` when even ``maximum`` seeds do not (a difference far inside the seed noise)."""
    if not (std >= 0 and delta > 0 and math.isfinite(std) and math.isfinite(delta)):
        raise ValueError(f"std must be >= 0 and delta > 0 (finite), got {std!r} and {delta!r}")
    _check(max(minimum, 2), comparisons, power_, alpha)
    if std == 0:
        return max(minimum, 2)
    effect = delta / std
    low, high = max(minimum, 2), maximum
    if power(high, effect, comparisons, alpha) < power_:
        raise ValueError(f"a difference of {delta:g} at a seed std of {std:g} needs more than {maximum} seeds")
    while low < high:  # the power grows with the seeds: the first n that reaches it
        mid = (low + high) // 2
        if power(mid, effect, comparisons, alpha) >= power_:
            high = mid
        else:
            low = mid + 1
    return low


def pooled_std(per_entry: Sequence[Sequence[float]]) -> float:
    """The seeds' standard deviation pooled over entries: sqrt of the degrees-of-freedom-weighted mean of the
    entries' sample variances (entries with fewer than two seeds add nothing)."""
    arrays = [np.asarray(x, np.float64).ravel() for x in per_entry]
    dof = sum(a.size - 1 for a in arrays if a.size > 1)
    if dof == 0:
        raise ValueError("pooled std: no entry has two seeds")
    return float(math.sqrt(sum(np.var(a, ddof=1) * (a.size - 1) for a in arrays if a.size > 1) / dof))


def exploration_matters(per_entry: Mapping[str, Sequence[float]]) -> dict:
    """One task's figure: {"best", "worst" (entry names), "spread" (best mean - worst mean), "pooled_std",
    "figure" (spread / pooled_std; inf when the pooled std is 0 and the spread is not)}."""
    if len(per_entry) < 2:
        raise ValueError("exploration matters: a task needs at least two entries")
    means = {k: float(np.mean(v)) for k, v in per_entry.items()}
    best, worst = max(means, key=means.get), min(means, key=means.get)
    spread, std = means[best] - means[worst], pooled_std(list(per_entry.values()))
    figure = spread / std if std > 0 else (math.inf if spread > 0 else 0.0)
    return {"best": best, "worst": worst, "spread": spread, "pooled_std": std, "figure": figure}


def seed_plan(per_task: Mapping[str, Mapping[str, Sequence[float]]], anchors: Mapping[str, tuple[float, float]],
              fraction: float, comparisons: int, minimum: int = 10, maximum: int = 40, power_: float = POWER,
              alpha: float = ALPHA) -> list[dict]:
    """The seed rule on a pilot: ``per_task`` {task: {entry: the pilot's final returns per seed}}, ``anchors``
    {task: (random policy's return, reference return)}. One row per task: the pilot's seeds, ``pooled_std`` (return
    units and ``std_fraction`` of the range), ``delta`` (``fraction`` of the range), ``needed`` (``seeds_for``, None
    beyond ``maximum``), ``seeds`` (the count to run: ``needed`` capped at ``maximum``), ``detectable_fraction``
    (the difference, as a fraction of the range, that ``seeds`` detect with the power at level alpha /
    comparisons) and the task's ``exploration_matters`` figure (its spread also as ``spread_fraction``)."""
    if not 0 < fraction < 1:
        raise ValueError(f"the fraction of the range must lie in (0, 1), got {fraction!r}")
    if int(maximum) != maximum or maximum < minimum:
        raise ValueError(f"maximum ({maximum!r}) must be a whole number >= minimum ({minimum})")
    rows = []
    for task, entries in per_task.items():
        if task not in anchors:
            raise ValueError(f"{task}: no normalisation anchors (its range sets the difference that matters)")
        low, high = anchors[task]
        span = high - low
        std, delta = pooled_std(list(entries.values())), fraction * span
        try:
            needed = seeds_for(std, delta, comparisons, power_, alpha, minimum, maximum)
        except ValueError:  # beyond the cap (seeds_for's only other errors are bad arguments, checked above)
            needed = None
        seeds = maximum if needed is None else needed
        detectable = detectable_effect(seeds, comparisons, power_, alpha) * std / span
        matters = exploration_matters(entries)
        rows.append({"task": task, "entries": len(entries), "pilot_seeds": {k: len(v) for k, v in entries.items()},
                     "range": [low, high], "pooled_std": std, "std_fraction": std / span, "delta": delta,
                     "needed": needed, "seeds": seeds, "capped": needed is None, "detectable_fraction": detectable,
                     **{f"matters_{k}": v for k, v in matters.items()},
                     "spread_fraction": matters["spread"] / span})
    return rows


def cpu_per_seed(cost_cells: Sequence[Mapping]) -> dict[str, float]:
    """{task: CPU seconds per seed of one cell}: the mean over a pilot's finished cells that recorded their CPU
    (``cost.json``'s ``cells``) of the cell's CPU over its seeds. A projection's unit, not a measurement of a larger
    cell: a cell of more seeds steps and updates them in one program, whose CPU grows at most about linearly with
    them (the vmapped updates share work, the compile is paid once), so a projection from it leans high."""
    per = {}
    for c in cost_cells:
        if c.get("status") == "done" and c.get("cpu_seconds") and c.get("seeds"):
            per.setdefault(c["task"], []).append(float(c["cpu_seconds"]) / int(c["seeds"]))
    return {t: float(np.mean(v)) for t, v in per.items()}


def project_cost(rows: list[dict], per_seed: Mapping[str, float], entries: int) -> float:
    """Adds each seed-plan row's ``projected_cpu_hours`` (its planned seeds x ``entries`` cells x the pilot's CPU
    per seed; None where the pilot has no CPU record for the task) and returns their total in hours."""
    if entries < 1:
        raise ValueError(f"entries must be at least 1, got {entries}")
    total = 0.0
    for r in rows:
        cost = per_seed.get(r["task"])
        r["cpu_per_seed"] = cost
        r["projected_cpu_hours"] = None if cost is None else cost * r["seeds"] * entries / 3600
        total += r["projected_cpu_hours"] or 0.0
    return total


if __name__ == "__main__":  # the command's parsing and files are the rendering side's
    import sys

    from experiments.analysis.render.power import main

    sys.exit(main())
