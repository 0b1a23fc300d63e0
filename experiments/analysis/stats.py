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

from experiments.grid.methods import BASELINE, METHOD_NAMES

FINAL_DEFINITION = ("final return of a seed = mean of its last max(1, floor(T/10)) evaluations (the last 10% "
                    "of its T evaluations, at least 1); each evaluation is the mean return of `run.eval_episodes` "
                    "deterministic episodes of the student")
STATS_DEFINITION = ("mean ± std: over seeds, sample std (ddof=1); 95% CI: mean ± t(0.975, n-1)·s/√n (Student t "
                    "over the n seeds); p: two-sided Welch t-test (scipy.stats.ttest_ind, equal_var=False) of the "
                    "seeds' final returns (in the JSON twin's `welch`: Meta (independent) vs {baseline})")


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
    from metapg_jax.host.runfiles import json_number

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
    se, df = _welch_se_df(a, b)
    if se == 0:
        return diff, 0.0
    return diff, float(stats.t.ppf(0.5 + level / 2, df) * se)


def _welch_se_df(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """The standard error of mean(a) − mean(b), sqrt(s_a^2/n_a + s_b^2/n_b), and its Welch-Satterthwaite degrees of
    freedom (NaN when both variances are 0); a and b have at least 2 values each."""
    va, vb = np.var(a, ddof=1) / a.size, np.var(b, ddof=1) / b.size
    if va + vb == 0:
        return 0.0, math.nan
    return math.sqrt(va + vb), float((va + vb) ** 2 / (va ** 2 / (a.size - 1) + vb ** 2 / (b.size - 1)))


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


# -- aggregate scores over tasks (Agarwal et al., NeurIPS 2021, "Deep RL at the Edge of the Statistical
# Precipice"; the estimators of their `rliable` package, written here on NumPy) ----------------------------
#
# Scores are normalised per task (``normalise``) and given as one array of per-seed scores per task (tasks may
# have different seed counts). Point estimates pool the seeds of every task; intervals come from the
# *stratified* bootstrap: each replicate resamples every task's seeds with replacement, independently per task
# (and, for the probability of improvement, independently per method), and the 95% interval is the 2.5th and
# 97.5th percentiles of the replicates. The generator is seeded: the same inputs give the same numbers.

AGGREGATE_DEFINITION = (
    "normalised score = (return − random policy's return) / (reference return − random policy's return), per "
    "task; IQM: mean of the middle 50% of all seeds' normalised scores pooled over the tasks (scipy.stats."
    "trim_mean, 25% cut each side); optimality gap: mean of max(0, 1 − score); P(X > Y): per task, the "
    "probability that a seed of X scores above a seed of Y (ties count 1/2: Mann-Whitney U / (n·m)), averaged "
    "over the tasks; [lo, hi]: 95% stratified percentile bootstrap ({reps:,} replicates, seeds resampled "
    "within each task; generator seed {seed})")
BOOTSTRAP_REPS = 20_000
BOOTSTRAP_SEED = 0


def normalise(returns: Sequence[float], low: float, high: float) -> np.ndarray:
    """(returns − low) / (high − low): 0 at ``low`` (a random policy's return), 1 at ``high`` (the reference,
    above ``low``: a reversed pair would reverse the order of the scores)."""
    if not (math.isfinite(low) and math.isfinite(high) and high > low):
        raise ValueError(f"normalisation needs finite anchors with the reference above the random policy's "
                         f"return, got low={low}, high={high}")
    return (np.asarray(returns, np.float64) - low) / (high - low)


def iqm(scores: np.ndarray, axis: int | None = None) -> np.ndarray:
    """Interquartile mean: the mean of the middle 50% (``scipy.stats.trim_mean``, 25% cut from each end)."""
    from scipy import stats

    return stats.trim_mean(scores, 0.25, axis=axis)


def optimality_gap(scores: np.ndarray, axis: int | None = None, gamma: float = 1.0) -> np.ndarray:
    """The mean shortfall from ``gamma``: mean of max(0, gamma − score)."""
    return np.mean(np.maximum(gamma - np.asarray(scores, np.float64), 0.0), axis=axis)


AGGREGATES = {"IQM": iqm, "mean": lambda x, axis=None: np.mean(x, axis=axis), "optimality gap": optimality_gap}


def _check_tasks(per_task: Sequence[Sequence[float]], what: str) -> list[np.ndarray]:
    arrays = [np.asarray(x, np.float64).ravel() for x in per_task]
    if not arrays or any(a.size == 0 for a in arrays):
        raise ValueError(f"{what}: every task needs at least one seed")
    if any(not np.all(np.isfinite(a)) for a in arrays):
        raise ValueError(f"{what}: scores must be finite")
    return arrays


def _resample(rng: np.random.Generator, per_task: list[np.ndarray], reps: int) -> list[np.ndarray]:
    """One (reps, n_task) array per task: each row a resample with replacement of that task's seeds."""
    return [a[rng.integers(0, a.size, size=(reps, a.size))] for a in per_task]


def _percentiles(replicates: np.ndarray, level: float) -> tuple[float, float]:
    lo, hi = np.percentile(replicates, [50 * (1 - level), 50 * (1 + level)])
    return float(lo), float(hi)


def aggregate_interval(per_task: Sequence[Sequence[float]], statistic=iqm, reps: int = BOOTSTRAP_REPS,
                       seed: int = BOOTSTRAP_SEED, level: float = 0.95) -> tuple[float, float, float]:
    """(point, lo, hi): ``statistic`` (e.g. ``iqm``, ``optimality_gap``) of the seeds' scores pooled over the
    tasks, and its stratified percentile-bootstrap interval."""
    arrays = _check_tasks(per_task, "aggregate")
    point = float(statistic(np.concatenate(arrays)))
    replicates = statistic(np.concatenate(_resample(np.random.default_rng(seed), arrays, reps), axis=1), axis=1)
    return (point, *_percentiles(replicates, level))


def _p_improvement(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """P(X > Y) + P(X = Y) / 2 over the last two axes' pairs (x: (..., n), y: (..., m))."""
    diff = x[..., :, None] - y[..., None, :]
    return np.mean((diff > 0) + 0.5 * (diff == 0), axis=(-2, -1))


def probability_of_improvement(x_per_task: Sequence[Sequence[float]], y_per_task: Sequence[Sequence[float]],
                               reps: int = BOOTSTRAP_REPS, seed: int = BOOTSTRAP_SEED,
                               level: float = 0.95) -> tuple[float, float, float]:
    """(point, lo, hi): the average over tasks of P(a seed of X scores above a seed of Y), ties 1/2 (rliable's
    ``probability_of_improvement``: Mann-Whitney U / (n·m) per task). Scores need not be normalised: the
    statistic only compares X and Y within a task. X's and Y's seeds are resampled independently per task."""
    xs, ys = _check_tasks(x_per_task, "probability of improvement"), _check_tasks(y_per_task, "probability of improvement")
    point = float(np.mean(improvement_per_task(xs, ys)))
    rng = np.random.default_rng(seed)
    bx, by = _resample(rng, xs, reps), _resample(rng, ys, reps)
    replicates = np.mean([_p_improvement(x, y) for x, y in zip(bx, by)], axis=0)
    return (point, *_percentiles(replicates, level))


def improvement_per_task(x_per_task: Sequence[Sequence[float]], y_per_task: Sequence[Sequence[float]]) -> list[float]:
    """P(a seed of X scores above a seed of Y), ties 1/2, on each task: the terms whose average is
    ``probability_of_improvement``'s point. Shows which tasks carry it (e.g. differences of a few points at a
    task's ceiling count as much as large ones)."""
    xs, ys = _check_tasks(x_per_task, "probability of improvement"), _check_tasks(y_per_task, "probability of improvement")
    if len(xs) != len(ys):
        raise ValueError(f"probability of improvement: {len(xs)} tasks for X, {len(ys)} for Y")
    return [float(_p_improvement(x, y)) for x, y in zip(xs, ys)]


def performance_profile(per_task: Sequence[Sequence[float]], taus: np.ndarray, reps: int = BOOTSTRAP_REPS,
                        seed: int = BOOTSTRAP_SEED, level: float = 0.95) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(fraction, lo, hi) at each threshold in ``taus``: the fraction of seeds, pooled over the tasks, whose
    normalised score exceeds tau, with its stratified bootstrap interval (Agarwal et al.'s run-score profile)."""
    arrays = _check_tasks(per_task, "performance profile")
    taus = np.asarray(taus, np.float64)
    point = np.mean(np.concatenate(arrays)[None, :] > taus[:, None], axis=1)
    pooled = np.concatenate(_resample(np.random.default_rng(seed), arrays, reps), axis=1)  # (reps, N)
    fractions = np.stack([np.mean(pooled > t, axis=1) for t in taus], axis=1)  # (reps, taus)
    lo, hi = np.percentile(fractions, [50 * (1 - level), 50 * (1 + level)], axis=0)
    return point, lo, hi


# -- per-task verdicts corrected for the number of comparisons ----------------------------------------------

def holm(pvalues: Sequence[float]) -> np.ndarray:
    """Holm-Bonferroni adjusted p-values of one family of tests (NaNs stay NaN and do not count toward m):
    sorted ascending, p_(i) becomes max over j <= i of min(1, (m − j + 1) · p_(j))."""
    p = np.asarray(pvalues, np.float64)
    out = np.full(p.shape, np.nan)
    ok = np.flatnonzero(np.isfinite(p))
    m = ok.size
    running = 0.0
    for rank, i in enumerate(ok[np.argsort(p[ok], kind="stable")]):
        running = max(running, min(1.0, (m - rank) * p[i]))
        out[i] = running
    return out


def tost(a: Sequence[float], b: Sequence[float], margin: float) -> float:
    """p of the two one-sided Welch t-tests for equivalence of the means within ±``margin``: the larger of the
    p-values of H0: mean(a) − mean(b) <= −margin and H0: mean(a) − mean(b) >= +margin. A small p says the
    difference lies inside the margin. NaN when either side has fewer than 2 values."""
    from scipy import stats

    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    if a.size < 2 or b.size < 2 or not margin > 0:
        return math.nan
    diff = float(a.mean() - b.mean())
    se, df = _welch_se_df(a, b)
    if se == 0:
        return 0.0 if abs(diff) < margin else 1.0
    p_low = stats.t.sf((diff + margin) / se, df)    # H0: diff <= -margin
    p_high = stats.t.cdf((diff - margin) / se, df)  # H0: diff >= +margin
    return float(max(p_low, p_high))


VERDICTS = ("better", "worse", "equivalent", "inconclusive")  # what ``corrected_verdict`` can say


def corrected_verdict(diff: float, p_holm: float, p_tost_holm: float, alpha: float = 0.05) -> str:
    """'better' / 'worse' where the Holm-corrected difference test rejects (by the sign of ``diff``),
    'equivalent' where the Holm-corrected equivalence test (``tost``) does, else 'inconclusive'."""
    if math.isfinite(p_holm) and p_holm < alpha:
        return "better" if diff > 0 else "worse"
    if math.isfinite(p_tost_holm) and p_tost_holm < alpha:
        return "equivalent"
    return "inconclusive"


EQUIVALENCE_MARGIN = 0.05  # of a task's normalised range (reference − random return): the declared margin
VERDICT_DEFINITION = (
    "verdicts: two-sided Welch t-test of the seeds' final returns, Holm-corrected within its family (every "
    "comparison of the table against one baseline); 'better' / 'worse' where the corrected p < 0.05; "
    "'equivalent' where the two one-sided Welch tests (TOST) of a difference within ±{margin:.0%} of the "
    "task's normalised range (reference − random policy's return, results/normalisation.json), Holm-corrected "
    "in the same family, give p < 0.05; otherwise 'inconclusive' (read the CI: before the correction, a test "
    "of 8 seeds against 8 has 80% power only for differences of about 1.5 standard deviations, of 10 against "
    "10 about 1.3)").format(margin=EQUIVALENCE_MARGIN)


def judge_family(pairs: Sequence[tuple[Sequence[float], Sequence[float], float | None]]) -> list[dict]:
    """The corrected verdicts of one family of comparisons: ``pairs`` of (a's per-seed finals, b's, the
    equivalence margin in return units or None where the task has no anchors). Per pair, in order: the
    difference of the means a − b and its 95% Welch CI, Welch t and raw p, the Holm-corrected p, the TOST p of
    the margin (raw and Holm-corrected over the family's TOSTs) and ``corrected_verdict``'s word."""
    raw = [welch_test(a, b) for a, b, _ in pairs]
    equiv = [tost(a, b, margin) if margin is not None else math.nan for a, b, margin in pairs]
    p_holm, equiv_holm = holm([p for _, p in raw]), holm(equiv)
    out = []
    for (a, b, margin), (t, p), ph, pe, peh in zip(pairs, raw, p_holm, equiv, equiv_holm):
        diff, half = welch_difference(a, b)
        out.append({"difference": diff, "ci95": [diff - half, diff + half] if math.isfinite(half) else None,
                    "t": t, "p": p, "p_holm": float(ph), "margin": margin, "p_equivalence": pe,
                    "p_equivalence_holm": float(peh), "verdict": corrected_verdict(diff, float(ph), float(peh))})
    return out


def equivalence_margin(anchors: dict | None, task: str) -> float | None:
    """The task's equivalence margin in return units: ``EQUIVALENCE_MARGIN`` of its anchors' range (reference −
    random return); None where ``anchors`` has none for it (nothing is then judged equivalent)."""
    low_high = (anchors or {}).get(task)
    return None if low_high is None else EQUIVALENCE_MARGIN * (low_high[1] - low_high[0])


class VerdictFamily:
    """One family of corrected verdicts, the one way every table assembles its families: ``add`` each comparison
    (a key, a's and b's per-seed finals, the task whose anchors give the margin), then ``judge`` them together
    (``judge_family``: Holm-corrected within the family, 'equivalent' only by the TOST of the margin)."""

    def __init__(self, anchors: dict | None = None):
        self.anchors, self.keys, self.pairs = anchors, [], []

    def add(self, key, a: Sequence[float], b: Sequence[float], task: str) -> None:
        self.keys.append(key)
        self.pairs.append((a, b, equivalence_margin(self.anchors, task)))

    def judge(self) -> list[tuple]:
        """[(key, verdict)] in the order added (``judge_family``'s dicts)."""
        return list(zip(self.keys, judge_family(self.pairs)))
