"""What the explorers put in the buffer, from stored cells, computed: the behaviour rows (exploration-episode
returns, the teacher's scale, the distance of the exploring policy from the student, first and final) and the
coverage of the state space by each data source, with their bootstrap intervals. The files they become
(``behaviour.md`` / ``.json``, ``coverage.md`` / ``.json``): ``experiments.analysis.render.behaviour``."""

from __future__ import annotations

import math
import os
import warnings
from typing import Sequence

import numpy as np

from experiments.analysis.cells import BEHAVIOUR_METRICS
from experiments.grid.methods import BASELINE, META
from experiments.analysis.stats import BOOTSTRAP_REPS, BOOTSTRAP_SEED, final_returns, mean_std

# State coverage as numbers (the coverage table): the occupied cells of a grid over a 2-D projection, the
# k-NN spread, the distance to the student's states.
COVERAGE_CELLS = 20   # a 20 x 20 grid over the task's 2-D PCA projection
COVERAGE_K = 5        # the k of the k-NN spread
COVERAGE_DEFINITION = (
    "per task, every stored state (teacher, student, DDPG; early and late; every seed; the same number of states "
    "per seed and group, evenly thinned) is standardised with the pooled mean and std per dimension; occupied "
    "cells: the fraction of a {cells} x {cells} grid over a 2-D PCA projection fitted once per task on the pooled "
    "states (its box: the pooled 1st-99th percentiles per axis, states outside counted in the edge cells) that "
    "a seed's states fall in; {k}-NN spread: a seed's mean distance from each state to its {k}th nearest "
    "neighbour among its own states; distance to the student: a seed's mean distance from each state to the "
    "nearest state of the student's (Meta's D1) of the same seed index and phase (for the student itself: to its "
    "nearest other state). Mean over seeds with a 95% percentile bootstrap over seeds ({reps:,} replicates, "
    "seed {seed})").format(cells=COVERAGE_CELLS, k=COVERAGE_K, reps=BOOTSTRAP_REPS, seed=BOOTSTRAP_SEED)


def occupied_fraction(xy: np.ndarray, low: np.ndarray, high: np.ndarray, cells: int = COVERAGE_CELLS) -> float:
    """The fraction of a ``cells`` x ``cells`` grid over the box [low, high] that the 2-D points ``xy`` occupy
    (points outside the box count in the edge cells)."""
    xy = np.asarray(xy, np.float64)
    idx = np.clip(np.floor((xy - low) / np.where(high > low, high - low, 1.0) * cells), 0, cells - 1).astype(int)
    return float(np.unique(idx[:, 0] * cells + idx[:, 1]).size / cells ** 2)


def knn_distance(x: np.ndarray, k: int = COVERAGE_K) -> float:
    """The mean distance from each row of ``x`` to its ``k``-th nearest other row."""
    from scipy.spatial import cKDTree

    x = np.asarray(x, np.float64)
    if x.shape[0] <= k:
        raise ValueError(f"{x.shape[0]} states: a {k}-NN distance needs more than {k}")
    dist, _ = cKDTree(x).query(x, k=k + 1)  # the first neighbour is the state itself
    return float(dist[:, k].mean())


def nearest_distance(x: np.ndarray, y: np.ndarray) -> float:
    """The mean distance from each row of ``x`` to the nearest row of ``y``."""
    from scipy.spatial import cKDTree

    dist, _ = cKDTree(np.asarray(y, np.float64)).query(np.asarray(x, np.float64), k=1)
    return float(dist.mean())


BEHAVIOUR_COLUMNS = tuple(zip(BEHAVIOUR_METRICS, ("exploration-episode return", "teacher log-std",
                                                  "teacher-student distance", "meta reward")))


def _seed_mean_first_final(values: np.ndarray) -> dict:
    """A behaviour metric's (seeds, T) chunks: the seed mean of the first chunk, and the seeds' mean and std
    of the final window (the final return's: the last max(1, floor(T/10)) chunks); NaN (a chunk where no
    exploration episode ended) is left out of every mean."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an all-NaN column is reported as n/a
        final = final_returns(values)
        final = final[np.isfinite(final)]
        mean, std = mean_std(final)
        return {"first": float(np.nanmean(values[:, 0])), "final_mean": mean, "final_std": std,
                "final_seeds": int(final.size)}


def behaviour_rows(results: dict, tasks: Sequence[str], methods: Sequence[str]) -> list[dict]:
    """What the explorer put in the buffer, per finished cell that logged it (``cells.BEHAVIOUR_METRICS``):
    the return of the exploration episodes (DDPG: the noisy or perturbed student; Meta: the teacher's D0)
    and, for a teacher, its log-std, its RMS distance to the student's action on D0 and the meta reward,
    each at the first chunk and over the final window (``_seed_mean_first_final``); the final evaluation
    return of the same cell for reference."""
    rows = []
    for task in tasks:
        for m in methods:
            r = results.get((task, m))
            if r is None or not r.complete or not r.behaviour:
                continue
            rows.append({"task": task, "method": m, "n": r.num_seeds, "budget": r.budget,
                         "eval_final": float(r.final().mean()),
                         **{k: _seed_mean_first_final(r.behaviour[k]) for k, _ in BEHAVIOUR_COLUMNS
                            if k in r.behaviour}})
    return rows


# ---------------------------------------------------------------------------------------------- coverage

COVERAGE_GROUPS = (("teacher", "teacher (Meta's D0)"), ("student", "student (Meta's D1)"), ("ddpg", "noise baseline"))


def coverage_rows(results: dict, tasks: Sequence[str], baseline: str = BASELINE) -> dict:
    """State coverage as numbers (``COVERAGE_DEFINITION``) for every task whose Meta (independent) and
    ``baseline`` cells stored ``visits.npz`` (the states of Figure 4): per group (teacher, student, the
    baseline; early and late) the occupied cells, the k-NN spread and the distance to the student's states,
    each a mean over seeds with its bootstrap interval; and per task and phase the comparisons Figure 4 is
    read for: teacher − baseline (occupied cells, spread; independent seeds) and the teacher's distance to
    the student's states − the student's own (paired by seed: the same runs). ``{"rows": [...],
    "comparisons": [...]}``."""
    from sklearn.decomposition import PCA

    from experiments.analysis.render import figures
    from experiments.analysis.cells import thin_visits

    out = {"rows": [], "comparisons": []}
    for task in tasks:
        a, b = results.get((task, META)), results.get((task, baseline))
        paths = [None if r is None else os.path.join(r.path, "visits.npz") for r in (a, b)]
        if None in paths or not all(os.path.exists(p) for p in paths):
            continue
        with np.load(paths[0]) as va, np.load(paths[1]) as vb:
            per_seed = figures.visitation_per_seed(thin_visits(dict(va)), thin_visits(dict(vb)))
        per_seed = {k: [x for x in v if len(x)] for k, v in per_seed.items()}
        sizes = [len(x) for v in per_seed.values() for x in v]
        if not sizes or min(sizes) <= COVERAGE_K or not per_seed[("late", "student")]:
            continue
        n, rng = min(sizes), np.random.default_rng(0)
        per_seed = {k: [figures.subsample(x, n, rng) for x in v] for k, v in per_seed.items()}
        pooled = np.concatenate([x for v in per_seed.values() for x in v], 0)
        mu, sd = pooled.mean(0), pooled.std(0)
        sd = np.where(sd > 1e-8, sd, 1.0)
        z = {k: [(x - mu) / sd for x in v] for k, v in per_seed.items()}
        pca = PCA(n_components=2, random_state=0).fit((pooled - mu) / sd)
        proj = pca.transform((pooled - mu) / sd)
        low, high = np.percentile(proj, 1, axis=0), np.percentile(proj, 99, axis=0)
        values = {}
        for (when, who), xs in z.items():
            if not xs:
                continue
            students = z[(when, "student")]
            values[(when, who)] = {
                "occupied": [occupied_fraction(pca.transform(x), low, high) for x in xs],
                "spread": [knn_distance(x) for x in xs],
                "to_student": ([knn_distance(x, 1) for x in xs] if who == "student" else
                               [nearest_distance(x, students[i % len(students)]) for i, x in enumerate(xs)])}
            out["rows"].append({"task": task, "phase": when, "group": who, "seeds": len(xs), "states_per_seed": n,
                                **{m: dict(zip(("mean", "lo", "hi"), bootstrap_mean(v)))
                                   for m, v in values[(when, who)].items()}})
        for when in ("early", "late"):
            t, d, st = values.get((when, "teacher")), values.get((when, "ddpg")), values.get((when, "student"))
            if t is None:
                continue
            comps = []
            if d is not None:
                comps += [("occupied", "teacher − noise baseline", bootstrap_difference(t["occupied"], d["occupied"])),
                          ("spread", "teacher − noise baseline", bootstrap_difference(t["spread"], d["spread"]))]
            if st is not None and len(st["to_student"]) == len(t["to_student"]):
                paired = np.asarray(t["to_student"]) - np.asarray(st["to_student"])
                comps.append(("to_student", "teacher − student (paired by seed)", bootstrap_mean(paired)))
            for measure, what, (diff, lo, hi) in comps:
                out["comparisons"].append({"task": task, "phase": when, "measure": measure, "comparison": what,
                                           "difference": diff, "lo": lo, "hi": hi,
                                           "reading": "higher" if lo > 0 else "lower" if hi < 0 else "no clear difference"})
    return out


# -- bootstrap intervals of a mean and of a difference of means over seeds (the coverage table's) --------------

def bootstrap_mean(values: Sequence[float], level: float = 0.95, reps: int = BOOTSTRAP_REPS,
                   seed: int = BOOTSTRAP_SEED) -> tuple[float, float, float]:
    """(mean, lo, hi): the mean of ``values`` (one per seed) and its percentile bootstrap interval over them
    (seeded: the same values give the same interval); for paired differences, pass the per-seed differences."""
    x = np.asarray(values, np.float64)
    if x.size < 2:
        return (float(x.mean()) if x.size else math.nan), math.nan, math.nan
    rng = np.random.default_rng(seed)
    means = x[rng.integers(0, x.size, (reps, x.size))].mean(1)
    lo, hi = np.percentile(means, [50 * (1 - level), 50 * (1 + level)])
    return float(x.mean()), float(lo), float(hi)


def bootstrap_difference(a: Sequence[float], b: Sequence[float], level: float = 0.95, reps: int = BOOTSTRAP_REPS,
                         seed: int = BOOTSTRAP_SEED) -> tuple[float, float, float]:
    """(mean(a) − mean(b), lo, hi): the difference of two independent groups' means (one value per seed) and its
    percentile bootstrap interval, each group's seeds resampled on their own (seeded)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    diff = float(a.mean() - b.mean())
    if a.size < 2 or b.size < 2:
        return diff, math.nan, math.nan
    rng = np.random.default_rng(seed)
    reps_a = a[rng.integers(0, a.size, (reps, a.size))].mean(1)
    reps_b = b[rng.integers(0, b.size, (reps, b.size))].mean(1)
    lo, hi = np.percentile(reps_a - reps_b, [50 * (1 - level), 50 * (1 + level)])
    return diff, float(lo), float(hi)
