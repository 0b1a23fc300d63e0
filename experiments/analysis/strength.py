"""Our student beside a reference implementation's (CleanRL's, ``experiments.strength.cleanrl``) on the same task and
budget, compared like with like: the returns of the training episodes.

The reference logs each training episode's return at the env step it ended (a CSV of ``step,episodic_return`` per
seed); our run records ``train_return`` per chunk, the mean return of the exploring episodes that ended in it. The
reference's episodes are binned into our chunks (an episode belongs to the first chunk whose last env step is at or
after the step it ended), so both sides have one number per chunk and seed: the mean return of the episodes that
ended in it (none where no episode ended). A seed's final return is the mean of its chunk numbers over the chunks
that end in the last ``FINAL_FRACTION`` of the budget. Per side: the seeds' finals, their mean and 95% t-interval;
between the sides: the difference (ours − reference) with its 95% Welch interval and its size in pooled seed
standard deviations. **The rule**: a difference larger than the seeds' pooled std is "beyond the seeds' spread", a
defect to find before any benchmark leans on the student; within it, "within the seeds' spread". Our evaluation
returns (the deterministic policy) have no counterpart on the reference's side and are never compared with it.

    python -m experiments.analysis.strength --reference 'OUT/cleanrl-td3-hopper-seed*.csv' \\
        --ours runs/strength/ours-modern-td3-hopper --name td3-hopper --out results/measurements/strength-cleanrl
"""

from __future__ import annotations

import csv
import math
import warnings
from typing import Sequence

import numpy as np

from experiments.analysis.power import pooled_std
from experiments.analysis.stats import t_interval, welch_difference

FINAL_FRACTION = 0.1


def read_episodes(path: str) -> list[tuple[int, float]]:
    """(env step at the episode's end, its return) from a reference run's CSV."""
    with open(path) as f:
        rows = list(csv.DictReader(f))
    if rows and set(rows[0]) != {"step", "episodic_return"}:
        raise ValueError(f"{path}: expected the columns step,episodic_return, got {','.join(rows[0])}")
    return [(int(r["step"]), float(r["episodic_return"])) for r in rows]


def bin_episodes(episodes: Sequence[tuple[int, float]], chunk_ends: Sequence[int]) -> np.ndarray:
    """(chunks,) mean return of the episodes that ended in each chunk (NaN where none did): an episode ending at step
    s belongs to the first chunk whose end is >= s; episodes after the last chunk's end are left out."""
    ends = np.asarray(chunk_ends, np.int64)
    sums, counts = np.zeros(ends.size), np.zeros(ends.size)
    for step, ret in episodes:
        i = int(np.searchsorted(ends, step, side="left"))
        if i < ends.size:
            sums[i] += ret
            counts[i] += 1
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)


def final_of(curve: np.ndarray, chunk_ends: Sequence[int], steps: int) -> float:
    """Mean of a seed's chunk numbers over the chunks ending after (1 − FINAL_FRACTION) × ``steps`` (NaN if none
    of them holds an ended episode)."""
    last = np.asarray(curve, np.float64)[np.asarray(chunk_ends) > (1 - FINAL_FRACTION) * steps]
    last = last[np.isfinite(last)]
    return float(last.mean()) if last.size else math.nan


def _side(curves: np.ndarray, chunk_ends: Sequence[int], steps: int) -> dict:
    finals = [final_of(c, chunk_ends, steps) for c in curves]
    ok = [x for x in finals if math.isfinite(x)]
    mean, half = t_interval(ok)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a chunk where no seed's episode ended: NaN
        curve = np.nanmean(curves, axis=0)
    return {"finals": finals, "mean": mean, "ci95": [mean - half, mean + half], "curve": curve.tolist()}


def compare(reference: Sequence[Sequence[tuple[int, float]]], ours_steps: Sequence[int], ours_train: np.ndarray,
            budget: int) -> dict:
    """``reference``: each seed's episodes; ``ours_steps`` (chunks,) our chunks' last env steps; ``ours_train``
    (seeds, chunks) our ``train_return``; ``budget``: env steps per seed of both sides."""
    if not reference or not len(ours_train):
        raise ValueError("both sides need at least one seed")
    ends = [int(s) for s in ours_steps]
    if ends[-1] != budget:
        raise ValueError(f"our run ends at {ends[-1]:,} env steps, not at the budget {budget:,}: compare finished runs")
    theirs = _side(np.stack([bin_episodes(e, ends) for e in reference]), ends, budget)
    ours = _side(np.asarray(ours_train, np.float64), ends, budget)
    a = [x for x in ours["finals"] if math.isfinite(x)]
    b = [x for x in theirs["finals"] if math.isfinite(x)]
    diff, half = welch_difference(a, b) if len(a) > 1 and len(b) > 1 else (math.nan, math.nan)
    spread = pooled_std([a, b]) if len(a) > 1 and len(b) > 1 else math.nan
    verdict = ("not judged: a side has fewer than two seeds with a final return" if not math.isfinite(spread) else
               "beyond the seeds' spread" if abs(diff) > spread else "within the seeds' spread")
    return {"budget": budget, "chunk_ends": ends, "final_fraction": FINAL_FRACTION, "ours": ours, "reference": theirs,
            "difference": diff, "difference_ci95": [diff - half, diff + half], "pooled_std": spread,
            "difference_in_std": diff / spread if spread and math.isfinite(spread) else math.nan,
            "verdict": verdict}


if __name__ == "__main__":  # the command's parsing and files are the rendering side's
    import sys

    from experiments.analysis.render.strength import main

    sys.exit(main())
