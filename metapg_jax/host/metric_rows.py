"""A chunk's metrics as rows: one JSON line per seed per chunk (``metrics.jsonl``) and per-cycle lines
(``cycles.jsonl``); a run's training time from its rows; learning curves and their plot.

The training program returns metrics per chunk (numpy, leading seed axis); nothing here runs inside
``jit``.
"""

from __future__ import annotations

import math
from typing import Iterable

import numpy as np

from metapg_jax.host.runfiles import json_number


def _train_return(cyc: dict, i: int) -> float | None:
    """Seed ``i``'s mean return of the exploring episodes completed in the chunk: weighted by the cycles'
    ``train_episodes`` where the explorer reports them (the built-in ones do), else the mean over cycles;
    None for an explorer that reports no ``train_return``, or when no episode ended."""
    if "train_return" not in cyc:
        return None
    if "train_episodes" not in cyc:
        v = np.asarray(cyc["train_return"][i], np.float64)
        return json_number(np.nanmean(v)) if np.isfinite(v).any() else None
    n_eps = cyc["train_episodes"][i].sum()
    return json_number(np.nansum(cyc["train_return"][i] * cyc["train_episodes"][i]) / n_eps) if n_eps > 0 else None


def chunk_rows(metrics: dict, chunk: int, wall_time: float, chunk_seconds: float | None = None) -> list[dict]:
    """One row per seed from a chunk's metrics (numpy, leading seed axis).

    ``wall_time``: seconds since this process started training (after compiling; a resumed call starts
    again from 0); ``chunk_seconds``: this chunk's own training time, so :func:`training_seconds` can add up
    a run's calls exactly."""
    cyc = metrics["cycle"]
    num_seeds = metrics["env_steps"].shape[0]
    rows = []
    for i in range(num_seeds):
        eval_ret = np.asarray(metrics["eval_return"][i])
        row = {
            "seed": i,
            "chunk": chunk,
            "env_steps": int(metrics["env_steps"][i]),
            "updates": int(metrics["updates"][i]),
            "eval_return": json_number(eval_ret.mean()),
            "eval_return_std": json_number(eval_ret.std()),
            "eval_length": json_number(np.mean(metrics["eval_length"][i])),
            "train_return": _train_return(cyc, i),
            "wall_time": round(wall_time, 3),
        }
        if chunk_seconds is not None:
            row["chunk_seconds"] = round(chunk_seconds, 3)
        for name, values in cyc.items():
            if name in ("train_return", "train_episodes", "finite") or np.ndim(values[i]) != 1:
                continue
            v = np.asarray(values[i], np.float64)
            row[name] = json_number(np.nanmean(v)) if np.isfinite(v).any() else None
        rows.append(row)
    return rows


def cycle_rows(metrics: dict, names: Iterable[str], first_cycle: int) -> list[dict]:
    """Per-cycle, per-seed rows of selected cycle metrics (used for the teacher's curves)."""
    cyc = metrics["cycle"]
    names = [n for n in names if n in cyc]
    if not names:
        return []
    num_seeds, num_cycles = np.shape(cyc[names[0]])[:2]
    return [
        {"seed": i, "cycle": first_cycle + c, **{n: json_number(cyc[n][i][c]) for n in names}}
        for i in range(num_seeds) for c in range(num_cycles)
    ]


# Fields of the rows that are not metrics: which seed, which chunk or cycle, and the x axis.
NOT_SCALARS = frozenset({"seed", "chunk", "cycle", "env_steps"})


def scalars(row: dict) -> dict[str, float]:
    """A row's metrics as the loggers plot them (TensorBoard, W&B): every numeric field but ``NOT_SCALARS``; None
    (NaN or inf in the rows), NaN, booleans and non-numbers are left out."""
    return {k: float(v) for k, v in row.items() if k not in NOT_SCALARS and _is_number(v)}


def _is_number(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_)) \
        and math.isfinite(v)


def training_seconds(rows: list[dict]) -> tuple[float | None, bool]:
    """(seconds of training over all the calls that made these metrics rows, exact?); compile excluded;
    (None, False) for rows without times.

    Rows with ``chunk_seconds`` add up exactly. Older rows only have ``wall_time``, the time since their
    call started training: a chunk whose ``wall_time`` is below the previous chunk's starts a new call
    (a resume). That misses a resume whose first chunk took longer than all the previous call did (a
    call killed after a single chunk, say), so the result is then flagged not exact. The reproduce
    record's wall time misses calls killed before they could write it; this does not."""
    by_chunk: dict[int, dict] = {}
    for r in rows:
        if r.get("wall_time") is not None:
            by_chunk.setdefault(int(r["chunk"]), r)
    if not by_chunk:
        return None, False
    total, prev, exact = 0.0, None, True
    for chunk in sorted(by_chunk):
        r, wall = by_chunk[chunk], float(by_chunk[chunk]["wall_time"])
        if r.get("chunk_seconds") is not None:
            total += float(r["chunk_seconds"])
        else:
            exact = False
            total += wall if prev is None or wall < prev else wall - prev
        prev = wall
    return total, exact


def curves(rows: list[dict], key: str = "eval_return") -> tuple[np.ndarray, np.ndarray]:
    """(env_steps (T,), values (seeds, T)) from metrics rows."""
    seeds = sorted({r["seed"] for r in rows})
    by_seed = {s: sorted((r for r in rows if r["seed"] == s), key=lambda r: r["env_steps"]) for s in seeds}
    steps = np.array([r["env_steps"] for r in by_seed[seeds[0]]])
    length = min(len(v) for v in by_seed.values())
    values = np.array([[np.nan if r.get(key) is None else r[key] for r in by_seed[s][:length]] for s in seeds])
    return steps[:length], values


def plot_learning_curve(rows: list[dict], path: str, title: str, key: str = "eval_return",
                        ylabel: str = "evaluation return") -> None:
    """Mean ± std band over seeds with thin per-seed lines; x axis: env steps."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    steps, values = curves(rows, key)
    fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=120)
    for v in values:
        ax.plot(steps, v, lw=0.6, alpha=0.35, color="tab:blue")
    mean, std = np.nanmean(values, 0), np.nanstd(values, 0)
    ax.plot(steps, mean, lw=2.0, color="tab:blue", label=f"mean of {len(values)} seeds")
    ax.fill_between(steps, mean - std, mean + std, color="tab:blue", alpha=0.2, label="± std")
    ax.set_xlabel("environment steps")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
