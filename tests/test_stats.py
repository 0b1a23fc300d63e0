"""experiments.analysis.stats: final returns, t intervals and Welch tests against formulas written out here; the aggregate scores over tasks (IQM, optimality gap, probability of improvement,
performance profiles, stratified bootstrap intervals), Holm's correction and the equivalence test.

The aggregate numbers are checked against `rliable` 1.2.0 (Agarwal et al.'s package; it needs pandas < 3, so it
is not a dependency) on the fixed scores below, computed with rliable 1.2.0, arch 7.2.0, numpy 2.4.6:

    from rliable import metrics, library
    metrics.aggregate_iqm(X), metrics.aggregate_optimality_gap(X, 1.0), metrics.probability_of_improvement(X, Y)
    library.get_interval_estimates({"X": X}, lambda s: np.array([metrics.aggregate_iqm(s),
        metrics.aggregate_optimality_gap(s, 1.0)]), reps=50000)
    library.get_interval_estimates({"X,Y": (X, Y)}, metrics.probability_of_improvement, reps=50000)
    library.create_performance_profile({"X": X}, [0.25, 0.5, 1.0], reps=50000)

(X, Y: 5 runs x 3 tasks.) The point estimates are equal; the intervals come from other random draws and agree
to the bootstrap's Monte Carlo error.
"""

import math

import numpy as np
import pytest
from scipy import stats as sps

from experiments.analysis import stats
from experiments.analysis.stats import (final_returns, first_step_reaching, mean_std, num_final_evaluations, t_interval,
                                     welch_difference, welch_test)

X = np.array([[0.10, 0.55, 1.20], [0.35, 0.55, 0.90], [0.80, 0.20, 1.05], [0.05, 0.70, 0.40], [0.60, 0.95, 1.30]])
Y = np.array([[0.20, 0.55, 0.80], [0.30, 0.10, 0.85], [0.15, 0.40, 1.10], [0.45, 0.25, 0.60], [0.05, 0.50, 0.95]])
RLIABLE = {  # rliable 1.2.0's numbers for X and Y (the module's docstring)
    "iqm": (0.6444444444444444, 0.44999999999999996, 0.8111111111111111),
    "optimality gap": (0.39, 0.2633333333333334, 0.5233333333333332),
    "P(X > Y)": (0.7000000000000001, 0.48666666666666664, 0.8933333333333332),
    "profile": ([0.8, 0.6666666666666666, 0.2], [0.6, 0.4666666666666667, 0.06666666666666667],
                [1.0, 0.8666666666666667, 0.3333333333333333]),
}
MC = 0.02  # the intervals' Monte Carlo tolerance (50,000 replicates there, 20,000 here)


def test_aggregates_and_their_intervals_equal_rliables():
    per_task = X.T  # one array of seeds per task
    got = stats.aggregate_interval(per_task, stats.iqm)
    assert got[0] == pytest.approx(RLIABLE["iqm"][0], abs=1e-12)
    assert got[1:] == pytest.approx(RLIABLE["iqm"][1:], abs=MC)
    got = stats.aggregate_interval(per_task, stats.optimality_gap)
    assert got[0] == pytest.approx(RLIABLE["optimality gap"][0], abs=1e-12)
    assert got[1:] == pytest.approx(RLIABLE["optimality gap"][1:], abs=MC)
    got = stats.probability_of_improvement(X.T, Y.T)
    assert got[0] == pytest.approx(RLIABLE["P(X > Y)"][0], abs=1e-12)
    assert got[1:] == pytest.approx(RLIABLE["P(X > Y)"][1:], abs=MC)
    point, lo, hi = stats.performance_profile(per_task, np.array([0.25, 0.5, 1.0]))
    np.testing.assert_allclose(point, RLIABLE["profile"][0], atol=1e-12)
    np.testing.assert_allclose(lo, RLIABLE["profile"][1], atol=1 / 15 + 1e-9)  # fractions of 15 seeds
    np.testing.assert_allclose(hi, RLIABLE["profile"][2], atol=1 / 15 + 1e-9)


def test_the_estimators_follow_their_definitions():
    pooled = np.sort(X.ravel())
    assert stats.iqm(X.ravel()) == pytest.approx(pooled[3:12].mean())  # 15 scores: 3 cut from each end
    assert stats.optimality_gap(np.array([0.5, 1.5, 1.0, -0.5])) == pytest.approx((0.5 + 0 + 0 + 1.5) / 4)
    # P(X > Y) on one task is Mann-Whitney's U / (n m), ties counted 1/2: 4 of the 6 pairs above, 1 tie
    x, y = np.array([1.0, 2.0, 3.0]), np.array([2.0, 0.0])
    u = sps.mannwhitneyu(x, y, alternative="greater").statistic
    assert stats.probability_of_improvement([x], [y])[0] == pytest.approx(u / 6) == pytest.approx(4.5 / 6)
    # per task, the terms of the average: a tie at a ceiling counts 1/2 on its own task
    per_task = stats.improvement_per_task([x, np.full(3, 9.0)], [y, np.full(4, 9.0)])
    assert per_task == pytest.approx([4.5 / 6, 0.5])
    assert np.mean(per_task) == pytest.approx(stats.probability_of_improvement([x, np.full(3, 9.0)],
                                                                              [y, np.full(4, 9.0)])[0])
    np.testing.assert_allclose(stats.normalise([-10.0, 0.0, 30.0], -10.0, 30.0), [0.0, 0.25, 1.0])
    for low, high in ((2.0, 2.0), (3.0, 2.0), (0.0, math.inf)):  # equal, reversed, infinite
        with pytest.raises(ValueError, match="reference above the random policy"):
            stats.normalise([1.0], low, high)


def test_the_bootstrap_is_seeded_stratified_and_takes_tasks_of_any_seed_count():
    ragged = [np.array([0.1, 0.4, 0.3]), np.array([0.9, 1.1, 0.8, 1.0, 0.7]), np.array([0.5, 0.6])]
    a = stats.aggregate_interval(ragged, stats.iqm)
    assert a == stats.aggregate_interval(ragged, stats.iqm)  # same inputs, same numbers
    assert a[1] <= a[0] <= a[2]
    few = [stats.aggregate_interval(ragged, stats.AGGREGATES["mean"], reps=20, seed=seed) for seed in (0, 1)]
    assert few[0] != few[1]  # the draws come from the seeded generator
    # stratified: a task whose seeds all score the same contributes that score to every replicate, so with
    # every task constant the interval has no width
    constant = [np.full(4, 0.2), np.full(6, 0.7)]
    assert stats.aggregate_interval(constant, stats.AGGREGATES["mean"]) == pytest.approx((0.5, 0.5, 0.5))
    assert stats.probability_of_improvement(constant, constant) == pytest.approx((0.5, 0.5, 0.5))
    for bad, message in (([], "at least one seed"), ([np.array([])], "at least one seed"),
                         ([np.array([0.1, np.nan])], "finite")):
        with pytest.raises(ValueError, match=message):
            stats.aggregate_interval(bad, stats.iqm)
    with pytest.raises(ValueError, match="2 tasks for X, 1 for Y"):
        stats.probability_of_improvement(constant, constant[:1])
    with pytest.raises(ValueError, match="2 tasks for X, 1 for Y"):
        stats.improvement_per_task(constant, constant[:1])


def test_holm_on_a_textbook_example():
    # m = 4: sorted 0.005, 0.01, 0.03, 0.04 -> 4 x 0.005, 3 x 0.01, 2 x 0.03, max(2 x 0.03, 1 x 0.04)
    np.testing.assert_allclose(stats.holm([0.01, 0.04, 0.03, 0.005]), [0.03, 0.06, 0.06, 0.02])
    got = stats.holm([0.02, math.nan, 0.5])  # a missing test neither counts nor gets a p
    assert got[0] == pytest.approx(0.04) and math.isnan(got[1]) and got[2] == pytest.approx(0.5)
    assert stats.holm([0.6, 0.7])[1] == 1.0  # capped at 1


def test_the_equivalence_test_is_two_one_sided_welch_tests():
    rng = np.random.default_rng(0)
    a, b = 10 + rng.normal(0, 0.1, 8), 10.05 + rng.normal(0, 0.1, 8)
    margin = 0.5
    # each side is scipy's one-sided Welch test of the data shifted by the margin
    p_low = sps.ttest_ind(a + margin, b, equal_var=False, alternative="greater").pvalue
    p_high = sps.ttest_ind(a - margin, b, equal_var=False, alternative="less").pvalue
    assert stats.tost(a, b, margin) == pytest.approx(max(p_low, p_high))
    # equivalent: tight samples, close means, a wide margin
    assert stats.tost(a, b, margin) < 1e-6
    # not equivalent: the means differ by more than the margin
    far = b + 2.0
    assert stats.tost(a, far, margin) > 0.5 and stats.welch_test(a, far)[1] < 1e-6
    # inconclusive: the same means but so much spread that neither test can decide
    wide_a, wide_b = 10 + rng.normal(0, 5, 8), 10 + rng.normal(0, 5, 8)
    assert stats.tost(wide_a, wide_b, margin) > 0.05 and stats.welch_test(wide_a, wide_b)[1] > 0.05
    assert math.isnan(stats.tost(a, b[:1], margin)) and math.isnan(stats.tost(a, b, 0.0))


def test_corrected_verdicts():
    assert stats.corrected_verdict(+3.0, 0.01, 0.9) == "better"
    assert stats.corrected_verdict(-3.0, 0.01, 0.9) == "worse"
    assert stats.corrected_verdict(0.1, 0.6, 0.01) == "equivalent"
    assert stats.corrected_verdict(0.1, 0.06, 0.2) == "inconclusive"
    assert stats.corrected_verdict(0.1, math.nan, math.nan) == "inconclusive"


def test_a_family_is_judged_with_holm_on_both_tests():
    rng = np.random.default_rng(3)
    base = rng.normal(0.0, 0.2, 8)
    close = rng.normal(0.0, 0.2, 8)                   # within a margin of 1: equivalent
    far = base + 10.0                                  # far above: better, even corrected
    noisy = rng.normal(0.5, 5.0, 8)                    # wide: neither
    pairs = [(close, base, 1.0), (far, base, 1.0), (noisy, base, 1.0), (close, base, None)]
    got = stats.judge_family(pairs)
    assert [g["verdict"] for g in got] == ["equivalent", "better", "inconclusive", "inconclusive"]
    raw = [stats.welch_test(a, b)[1] for a, b, _ in pairs]
    np.testing.assert_allclose([g["p_holm"] for g in got], stats.holm(raw))
    tosts = [stats.tost(a, b, 1.0) for a, b, _ in pairs[:3]] + [math.nan]
    np.testing.assert_allclose([g["p_equivalence_holm"] for g in got], stats.holm(tosts))
    assert math.isnan(got[3]["p_equivalence"]) and got[3]["margin"] is None
    diff, half = stats.welch_difference(far, base)
    assert got[1]["difference"] == diff and got[1]["ci95"] == [diff - half, diff + half]
    # the correction counts the family: a raw p between 0.05/3 and 0.05 is 'better' alone, not among three
    a = base + 0.35
    p = stats.welch_test(a, base)[1]
    assert 0.05 / 3 < p < 0.05
    assert stats.judge_family([(a, base, None)])[0]["verdict"] == "better"
    null = (base, base + 0.0, None)
    assert stats.judge_family([(a, base, None), null, null])[0]["verdict"] == "inconclusive"


def test_final_returns_use_the_last_tenth_at_least_one():
    assert [num_final_evaluations(t) for t in (1, 5, 9, 10, 19, 20, 100, 167)] == [1, 1, 1, 1, 1, 2, 10, 16]
    values = np.arange(2 * 20, dtype=float).reshape(2, 20)
    np.testing.assert_allclose(final_returns(values), [(18 + 19) / 2, (38 + 39) / 2])
    np.testing.assert_allclose(final_returns(values[:, :3]), [2, 22])


def test_run_summary_is_the_tables_final_return_with_the_last_evaluation_apart():
    """summary.json's numbers (experiments.analysis.stats.run_summary): the mean of each seed's last 10% of
    evaluations, mean ± sample std over seeds; the last evaluation alone under its own name."""
    from experiments.analysis.stats import describe_final, run_summary

    values = np.arange(2 * 20, dtype=float).reshape(2, 20)  # finals 18.5 and 38.5
    s = run_summary(np.arange(1, 21) * 100, values)
    assert s["env_steps"] == 2000 and s["num_seeds"] == 2 and s["final_return_evaluations"] == 2
    assert s["final_return_per_seed"] == [18.5, 38.5] and s["final_return_mean"] == 28.5
    assert s["final_return_std"] == pytest.approx(np.sqrt(2 * 10.0 ** 2))  # sample std of 18.5, 38.5
    assert s["last_eval_return_per_seed"] == [19.0, 39.0] and s["last_eval_return_mean"] == 29.0
    assert describe_final(s) == ("final return 28.5 ± 14.1 (mean of the last 2 evaluations per seed; mean ± "
                                 "sample std over 2 seeds)")
    values[1, -1] = np.nan  # a seed without a finite last evaluation: None in JSON, not NaN
    assert run_summary(np.arange(1, 21), values)["last_eval_return_per_seed"] == [19.0, None]


def test_mean_std_t_interval_and_welch_match_the_formulas():
    a = np.array([1.0, 2.5, 4.0, 3.5])
    b = np.array([0.5, 1.0, 0.0])
    mean, std = mean_std(a)
    assert mean == pytest.approx(a.sum() / 4)
    assert std == pytest.approx(math.sqrt(((a - a.mean()) ** 2).sum() / 3))
    _, half = t_interval(a)
    assert half == pytest.approx(sps.t.ppf(0.975, 3) * std / math.sqrt(4))
    # Welch: t = (ma - mb) / sqrt(va/na + vb/nb), Welch-Satterthwaite df, two-sided p.
    va, vb = a.var(ddof=1) / 4, b.var(ddof=1) / 3
    t = (a.mean() - b.mean()) / math.sqrt(va + vb)
    df = (va + vb) ** 2 / (va ** 2 / 3 + vb ** 2 / 2)
    got_t, got_p = welch_test(a, b)
    assert got_t == pytest.approx(t) and got_p == pytest.approx(2 * sps.t.sf(abs(t), df))
    assert all(math.isnan(v) for v in welch_test(a, b[:1]))
    # The difference's Welch interval: t(0.975, df) * sqrt(va/na + vb/nb), scipy's own interval too.
    diff, half = welch_difference(a, b)
    assert diff == pytest.approx(a.mean() - b.mean())
    assert half == pytest.approx(sps.t.ppf(0.975, df) * math.sqrt(va + vb))
    ci = sps.ttest_ind(a, b, equal_var=False).confidence_interval(0.95)
    assert (diff - half, diff + half) == pytest.approx((ci.low, ci.high))
    assert math.isnan(welch_difference(a, b[:1])[1])
    assert math.isnan(t_interval([3.0])[1]) and math.isnan(mean_std([3.0])[1])


def test_first_step_reaching():
    steps = np.array([100, 200, 300, 400])
    assert first_step_reaching(steps, np.array([0.0, np.nan, 5.0, 7.0]), 5.0) == 300
    assert first_step_reaching(steps, np.array([0.0, 1.0, 2.0, 3.0]), 5.0) is None


def test_a_verdict_family_is_judge_family_with_each_tasks_margin():
    """``VerdictFamily``: the comparisons in the order added, each task's margin from its anchors (none without)."""
    rng = np.random.default_rng(3)
    a, b, c = (rng.normal(m, 1.0, 10) for m in (0.0, 0.1, 3.0))
    anchors = {"hopper": (0.0, 40.0)}
    family = stats.VerdictFamily(anchors)
    family.add("x", a, b, "hopper")
    family.add("y", c, b, "reacher")
    judged = family.judge()
    assert [k for k, _ in judged] == ["x", "y"]
    assert str([j for _, j in judged]) == str(stats.judge_family([(a, b, 2.0), (c, b, None)]))  # NaN != NaN
    assert judged[0][1]["margin"] == 2.0 and judged[1][1]["margin"] is None
    assert stats.equivalence_margin(None, "hopper") is None
