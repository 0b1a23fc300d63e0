"""Statistics of the stored results: final returns, mean ± std, t intervals, Welch's t-test,
first step reaching a threshold, number formatting, and the definitions written into the tables.

Definitions (also written into the files):

* a seed's *final* return is the mean of its last ``max(1, floor(T / 10))``
  evaluations, T the number of evaluations it has (each evaluation is itself the
  mean return of ``run.eval_episodes`` deterministic episodes);
* ± is the sample standard deviation over seeds (ddof=1);
* the 95% CI is mean ± t(0.975, n-1) · s / sqrt(n) over the n seeds' final returns;
* the p-value is the two-sided Welch t-test (``scipy.stats.ttest_ind(equal_var=False)``).

Small pure functions on NumPy arrays (unit-tested against hand-written formulas).
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from experiments.grid import BASELINE, METHOD_NAMES

FINAL_DEFINITION = ("final return of a seed = mean of its last max(1, floor(T/10)) evaluations (the last 10% "
                    "of its T evaluations, at least 1); each evaluation is the mean return of `run.eval_episodes` "
                    "deterministic episodes of the student")
STATS_DEFINITION = ("mean ± std: over seeds, sample std (ddof=1); 95% CI: mean ± t(0.975, n-1)·s/√n (Student t "
                    "over the n seeds); p: two-sided Welch t-test (scipy.stats.ttest_ind, equal_var=False) of the "
                    "seeds' final returns, Meta (independent) vs {baseline}")


def stats_definition(baseline: str = BASELINE) -> str:
    return STATS_DEFINITION.format(baseline=METHOD_NAMES.get(baseline, baseline))


def num_final_evaluations(num_evaluations: int, fraction: float = 0.1) -> int:
    """How many of the last evaluations make up the "final" return: max(1, floor(fraction * T))."""
    if num_evaluations <= 0:
        raise ValueError("no evaluations")
    return max(1, int(math.floor(fraction * num_evaluations + 1e-9)))


def final_returns(values: np.ndarray, fraction: float = 0.1) -> np.ndarray:
    """Per-seed final return from (seeds, T) evaluation returns: the mean of the last 10% (at least 1)."""
    values = np.asarray(values, np.float64)
    k = num_final_evaluations(values.shape[1], fraction)
    return np.nanmean(values[:, -k:], axis=1)


def run_summary(steps: np.ndarray, values: np.ndarray) -> dict:
    """A run's final return as summary.json and every command line give it: the tables' definitions
    (``FINAL_DEFINITION``; mean ± sample std over seeds, as ``mean_std``), from the evaluation returns
    ``values`` (seeds, T) at env steps ``steps`` (T,). The last evaluation alone is kept under
    ``last_eval_return_*``."""
    from metapg_jax.reporting import json_number

    values = np.asarray(values, np.float64)
    final = final_returns(values)
    mean, std = mean_std(final)
    last = values[:, -1]
    return {
        "env_steps": int(steps[-1]),
        "num_seeds": int(len(final)),
        "final_return_per_seed": [json_number(v) for v in final],
        "final_return_mean": json_number(mean),
        "final_return_std": json_number(std),
        "final_return_evaluations": num_final_evaluations(values.shape[1]),
        "final_return_definition": f"{FINAL_DEFINITION}; ± = sample std over seeds (ddof=1)",
        "last_eval_return_per_seed": [json_number(v) for v in last],
        "last_eval_return_mean": json_number(np.mean(last)),
    }


def describe_final(summary: dict) -> str:
    """'final return 12.3 ± 4.5 (mean of the last 2 evaluations per seed; mean ± std over 8 seeds)'."""
    mean, std = summary["final_return_mean"], summary["final_return_std"]
    k = summary["final_return_evaluations"]
    window = "the last evaluation" if k == 1 else f"mean of the last {k} evaluations"
    return (f"final return {fmt(mean, 1)} ± {fmt(std, 1)} ({window} per seed; mean ± sample std over "
            f"{summary['num_seeds']} seeds)")


def mean_std(x: Sequence[float]) -> tuple[float, float]:
    """(mean, sample std with ddof=1); std is NaN for fewer than 2 values."""
    x = np.asarray(x, np.float64)
    if x.size == 0:
        return math.nan, math.nan
    return float(np.mean(x)), float(np.std(x, ddof=1)) if x.size > 1 else math.nan


def t_interval(x: Sequence[float], level: float = 0.95) -> tuple[float, float]:
    """(mean, half-width) of the Student-t confidence interval of the mean; half-width NaN for n < 2."""
    from scipy import stats

    x = np.asarray(x, np.float64)
    n = x.size
    if n < 2:
        return (float(x.mean()) if n else math.nan), math.nan
    half = stats.t.ppf(0.5 + level / 2, n - 1) * np.std(x, ddof=1) / math.sqrt(n)
    return float(x.mean()), float(half)


def welch_test(a: Sequence[float], b: Sequence[float]) -> tuple[float, float]:
    """(t, two-sided p) of Welch's t-test of a vs b; NaNs when either has fewer than 2 values."""
    from scipy import stats

    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    if a.size < 2 or b.size < 2:
        return math.nan, math.nan
    res = stats.ttest_ind(a, b, equal_var=False)
    return float(res.statistic), float(res.pvalue)


def welch_difference(a: Sequence[float], b: Sequence[float], level: float = 0.95) -> tuple[float, float]:
    """(mean(a) - mean(b), half-width of its Welch confidence interval: t(level, Welch-Satterthwaite df) times
    sqrt(s_a^2/n_a + s_b^2/n_b)); half-width NaN when either has fewer than 2 values."""
    from scipy import stats

    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    diff = float(a.mean() - b.mean()) if a.size and b.size else math.nan
    if a.size < 2 or b.size < 2:
        return diff, math.nan
    va, vb = np.var(a, ddof=1) / a.size, np.var(b, ddof=1) / b.size
    if va + vb == 0:
        return diff, 0.0
    df = (va + vb) ** 2 / (va ** 2 / (a.size - 1) + vb ** 2 / (b.size - 1))
    return diff, float(stats.t.ppf(0.5 + level / 2, df) * math.sqrt(va + vb))


def verdict(a: Sequence[float], b: Sequence[float], alpha: float = 0.05) -> tuple[float, float, str]:
    """(t, p, word) of Welch's test of a vs b: word 'better' (mean(a) > mean(b)) or 'worse' at p < ``alpha``,
    else 'n.s.' (also when p is NaN: fewer than 2 values on a side)."""
    t, p = welch_test(a, b)
    if not (math.isfinite(p) and p < alpha):
        return t, p, "n.s."
    return t, p, "better" if float(np.mean(a)) > float(np.mean(b)) else "worse"


def first_step_reaching(steps: np.ndarray, curve: np.ndarray, threshold: float) -> int | None:
    """The first env step at which ``curve`` >= ``threshold``, or None if it never does."""
    curve = np.asarray(curve, np.float64)
    hit = np.where(np.isfinite(curve) & (curve >= threshold))[0]
    return int(np.asarray(steps)[hit[0]]) if hit.size else None


def fmt(x: float | None, digits: int | None = None) -> str:
    """A number for a table: 4 significant figures by default, 'n/a' for None/NaN."""
    if x is None or not math.isfinite(x):
        return "n/a"
    if digits is not None:
        return f"{x:.{digits}f}"
    ax = abs(x)
    if ax >= 1000:
        return f"{x:,.0f}"
    if ax >= 100:
        return f"{x:.0f}"
    if ax >= 10:
        return f"{x:.1f}"
    return f"{x:.2f}"


def fmt_p(p: float | None) -> str:
    if p is None or not math.isfinite(p):
        return "n/a"
    return f"{p:.2g}" if p >= 1e-4 else f"{p:.1e}"
