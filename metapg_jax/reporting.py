"""Host-side reporting: metrics files, atomic writes, progress bar, plots, summaries.

Nothing here runs inside ``jit``. The training program returns metrics per
chunk; the host turns them into one JSON line per seed per chunk
(``metrics.jsonl``, appended and flushed as they come), per-cycle lines for
the meta method (``cycles.jsonl``), a learning-curve PNG and ``summary.json``.
"""

from __future__ import annotations

import json
import math
import os
import sys
import tempfile
import time
from typing import Any, Iterable

import numpy as np


def provenance() -> dict:
    """The commit (and whether the tree had changes) and the machine, recorded with every run."""
    import platform
    import subprocess

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

    def git(*args):
        try:
            return subprocess.run(["git", *args], cwd=root, capture_output=True, text=True, timeout=10).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            return ""

    machine = {"platform": platform.platform(), "processor": platform.machine(),
               "cpu_count": os.cpu_count(), "python": platform.python_version()}
    try:
        import jax

        machine.update(jax_version=jax.__version__, jax_backend=jax.default_backend(),
                       jax_devices=[str(d) for d in jax.devices()])
    except Exception as err:  # noqa: BLE001 - provenance must never stop a run
        machine["jax_error"] = repr(err)
    return {"commit": git("rev-parse", "HEAD") or "unknown",
            "dirty": bool(git("status", "--porcelain", "--untracked-files=no")),
            "machine": machine}


def write_json_atomic(path: str, obj: Any) -> None:
    """Writes JSON to a temporary file in the same folder, then renames it over ``path``."""
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp-", suffix=".json")
    try:
        with os.fdopen(fd, "w") as f:
            json.dump(obj, f, indent=2, default=_jsonable)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _jsonable(x):
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(f"not JSON serialisable: {type(x)}")


def _clean(x: float) -> float | None:
    x = float(x)
    return None if math.isnan(x) or math.isinf(x) else x


class JsonlWriter:
    """Appends JSON lines and flushes after every batch, so a killed run keeps what it wrote."""

    def __init__(self, path: str):
        self.path = path
        self._f = open(path, "a")

    def write(self, rows: Iterable[dict]) -> None:
        for row in rows:
            self._f.write(json.dumps(row, default=_jsonable) + "\n")
        self._f.flush()
        os.fsync(self._f.fileno())

    def close(self) -> None:
        self._f.close()


def read_jsonl(path: str) -> list[dict]:
    """The rows of a JSONL file; a last line cut by a kill is skipped."""
    rows = []
    with open(path) as f:
        for line in f:
            if not line.strip():
                continue
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError:
                continue
    return rows


def savez_atomic(path: str, arrays: dict) -> None:
    """``np.savez_compressed`` to a temporary name in the same folder, then renamed over ``path``."""
    tmp = path + ".tmp.npz"
    np.savez_compressed(tmp, **arrays)
    os.replace(tmp, path)


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
        n_eps = cyc["train_episodes"][i].sum()
        row = {
            "seed": i,
            "chunk": chunk,
            "env_steps": int(metrics["env_steps"][i]),
            "updates": int(metrics["updates"][i]),
            "eval_return": _clean(eval_ret.mean()),
            "eval_return_std": _clean(eval_ret.std()),
            "eval_length": _clean(np.mean(metrics["eval_length"][i])),
            "train_return": _clean(np.nansum(cyc["train_return"][i] * cyc["train_episodes"][i]) / n_eps)
            if n_eps > 0 else None,
            "wall_time": round(wall_time, 3),
        }
        if chunk_seconds is not None:
            row["chunk_seconds"] = round(chunk_seconds, 3)
        for name, values in cyc.items():
            if name in ("train_return", "train_episodes", "finite") or np.ndim(values[i]) != 1:
                continue
            v = np.asarray(values[i], np.float64)
            row[name] = _clean(np.nanmean(v)) if np.isfinite(v).any() else None
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
        {"seed": i, "cycle": first_cycle + c, **{n: _clean(cyc[n][i][c]) for n in names}}
        for i in range(num_seeds) for c in range(num_cycles)
    ]


class Progress:
    """A tqdm bar over env steps with steps/s, ETA and the latest mean evaluation return."""

    def __init__(self, total_steps: int, num_seeds: int, desc: str, disable: bool | None = None):
        from tqdm import tqdm

        self.num_seeds = num_seeds
        self.start = time.perf_counter()
        self.bar = tqdm(total=total_steps, desc=desc, unit="step", dynamic_ncols=True,
                        disable=disable if disable is not None else False, file=sys.stderr,
                        bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}<{remaining}, {rate_fmt}{postfix}]")

    def update(self, env_steps: int, eval_returns: np.ndarray) -> None:
        self.bar.update(env_steps - self.bar.n)
        elapsed = time.perf_counter() - self.start
        self.bar.set_postfix_str(
            f"eval {np.mean(eval_returns):.1f} ± {np.std(eval_returns):.1f} | "
            f"{self.num_seeds * self.bar.n / max(elapsed, 1e-9):,.0f} total steps/s")

    def close(self) -> None:
        self.bar.close()


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


def summarize(rows: list[dict]) -> dict:
    """Final evaluation return per seed (the last evaluation) and mean ± std over seeds."""
    steps, values = curves(rows)
    final = values[:, -1]
    return {
        "env_steps": int(steps[-1]),
        "final_eval_return_per_seed": [_clean(v) for v in final],
        "final_eval_return_mean": _clean(np.nanmean(final)),
        "final_eval_return_std": _clean(np.nanstd(final)),
        "num_seeds": int(len(final)),
    }
