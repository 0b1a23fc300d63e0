"""The figures of the artefacts, from stored cells (``experiments.analysis.cells``): learning curves per task
(``curves_<task>.png``, Figure 3), teacher designs (``teacher_designs_idp.png``, Figure 2) and state
visitation jointly embedded in 2-D (``visitation_<task>.png``, Figure 4; t-SNE or PCA); and the
matplotlib helpers other reports use (``pyplot``, ``save_figure``).
"""

from __future__ import annotations

import os
from typing import Sequence

import numpy as np

from experiments.grid import methods as grid
from experiments.grid.methods import BASELINE, META, METHOD_NAMES, baseline_for, grid_label, task_name

# Line colour of each grid method in every figure.
METHOD_COLORS = {"meta-independent": "tab:red", "meta-variance": "tab:orange",
                 "ddpg-paramnoise": "tab:blue", "ddpg-normal": "tab:cyan"}


# ---------------------------------------------------------------------------------------------- matplotlib

def pyplot():
    """``matplotlib.pyplot`` on the Agg backend (files only, no display); imported when a figure is drawn."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path: str, build: dict) -> None:
    """Saves a PNG with the build's commit and time in its metadata."""
    fig.savefig(path, metadata={"Software": f"metapg-jax commit {build.get('commit') or 'unknown'}",
                                "Creation Time": build.get("built", "")})


# ---------------------------------------------------------------------------------------------- curves

def _plot_methods(ax, results: dict, task: str, methods: Sequence[str]) -> int:
    drawn = 0
    for m in methods:
        r = results.get((task, m))
        if r is None:
            continue
        mean, std = np.nanmean(r.values, 0), np.nanstd(r.values, 0)
        label = f"{METHOD_NAMES.get(m, m)} ({r.num_seeds} seeds" + ("" if r.complete else ", incomplete") + ")"
        color = METHOD_COLORS.get(m)
        ax.plot(r.steps, mean, lw=1.8, color=color, label=label)
        ax.fill_between(r.steps, mean - std, mean + std, color=color, alpha=0.18)
        drawn += 1
    ax.set_xlabel("environment steps")
    ax.set_ylabel("evaluation return")
    ax.grid(alpha=0.3)
    if drawn:
        ax.legend(loc="best", fontsize=7)
    return drawn


def write_curves(results: dict, tasks: Sequence[str], methods: Sequence[str], out_dir: str, build: dict,
                 preset: str, student: str = "ddpg") -> list[str]:
    """``curves_<task>.png`` per task with stored runs: mean ± std band over seeds per method (Figure 3)."""
    plt = pyplot()
    paths = []
    for task in tasks:
        if not any((task, m) in results for m in methods):
            continue
        fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=120)
        _plot_methods(ax, results, task, methods)
        ax.set_title(f"{task_name(task)} ({grid_label(preset, student)}): mean ± std over seeds", fontsize=10)
        fig.tight_layout()
        path = os.path.join(out_dir, f"curves_{task}.png")
        save_figure(fig, path, build)
        plt.close(fig)
        paths.append(path)
    return paths


def write_teacher_designs(results: dict, out_dir: str, build: dict, preset: str,
                          task: str = "inverted_double_pendulum", student: str = "ddpg") -> list[str]:
    """Independent vs variance teacher vs the grid's baseline, curves on one task (Figure 2)."""
    methods = ("meta-independent", "meta-variance", baseline_for(preset, student))
    if not any((task, m) in results for m in methods):
        return []
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=120)
    _plot_methods(ax, results, task, methods)
    ax.set_title(f"Teacher designs on {task_name(task)} ({grid_label(preset, student)})", fontsize=10)
    fig.tight_layout()
    short = "idp" if task == "inverted_double_pendulum" else task
    path = os.path.join(out_dir, f"teacher_designs_{short}.png")
    save_figure(fig, path, build)
    plt.close(fig)
    return [path]


# ---------------------------------------------------------------------------------------------- visitation

def visitation_per_seed(teacher_visits: dict, ddpg_visits: dict) -> dict:
    """{(when, who): [states (n_i, obs) of seed i]} for when in early/late and who in teacher/student/ddpg: the
    valid rows of each seed (``min(count, K)``; the ``*_late`` ring is in arbitrary order, which does not matter
    for a density or a coverage measure)."""
    def valid(v: dict, prefix: str, when: str) -> list[np.ndarray]:
        arr = np.asarray(v[f"{prefix}_{when}"], np.float64)      # (seeds, K, obs)
        counts = np.asarray(v[f"{prefix}_count"]).reshape(-1)
        k = arr.shape[1]
        return [arr[i, :min(int(counts[i]), k)] for i in range(arr.shape[0])]

    groups = {}
    for when in ("early", "late"):
        groups[(when, "teacher")] = valid(teacher_visits, "explore", when)
        groups[(when, "student")] = valid(teacher_visits, "student", when)
        groups[(when, "ddpg")] = valid(ddpg_visits, "explore", when)
    return groups


def visitation_groups(teacher_visits: dict, ddpg_visits: dict) -> dict:
    """{(row, col): states (n, obs)} for the 2x3 figure: rows early/late, cols teacher/student/DDPG; the seeds
    of ``visitation_per_seed`` pooled."""
    return {k: np.concatenate(parts, 0) if parts else np.zeros((0, np.asarray(teacher_visits["explore_early"]).shape[-1]))
            for k, parts in visitation_per_seed(teacher_visits, ddpg_visits).items()}


def subsample(x: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """At most n rows of x, without replacement."""
    if x.shape[0] <= n:
        return x
    return x[np.sort(rng.choice(x.shape[0], n, replace=False))]


def embed_2d(x: np.ndarray, method: str = "tsne", seed: int = 0) -> np.ndarray:
    """2-D embedding of standardised states: t-SNE (sklearn) or PCA (fast)."""
    x = np.asarray(x, np.float64)
    std = x.std(0)
    z = (x - x.mean(0)) / np.where(std > 1e-8, std, 1.0)
    if method == "pca":
        from sklearn.decomposition import PCA

        out = PCA(n_components=min(2, z.shape[1]), random_state=seed).fit_transform(z)
    elif method == "tsne":
        from sklearn.manifold import TSNE
        from threadpoolctl import threadpool_limits

        # One OpenMP thread: sklearn's Barnes-Hut t-SNE on a busy machine (e.g. next to a training run)
        # slows down ~100x from thread contention; single-threaded it takes ~10 s for 3000 points.
        with threadpool_limits(limits=1):
            out = TSNE(n_components=2, init="pca", perplexity=min(30.0, max(2.0, (len(z) - 1) / 3)),
                       random_state=seed).fit_transform(z)
    else:
        raise ValueError(f"unknown embedding {method!r}; use tsne or pca")
    if out.shape[1] < 2:
        out = np.concatenate([out, np.zeros((out.shape[0], 2 - out.shape[1]))], 1)
    return out


def write_visitation(results: dict, out_dir: str, build: dict, tasks: Sequence[str] | None = None,
                     embedding: str = "tsne", points_per_panel: int = 500, seed: int = 0,
                     baseline: str = BASELINE) -> list[str]:
    """``visitation_<task>.png`` for each of ``tasks`` (default the grid's, ``grid.tasks``) whose Meta
    (independent) and DDPG (``baseline``) cells both stored ``visits.npz``: teacher / student and DDPG states,
    early and late, jointly embedded in 2-D, with Gaussian-KDE contours (the paper's Figure 4, on
    InvertedDoublePendulum there)."""
    files = []
    for task in grid.tasks() if tasks is None else tasks:
        a, b = results.get((task, META)), results.get((task, baseline))
        if a is None or b is None:
            continue
        pa, pb = os.path.join(a.path, "visits.npz"), os.path.join(b.path, "visits.npz")
        if os.path.exists(pa) and os.path.exists(pb):
            from metapg_jax.config import from_dict

            files += _write_visitation_figure(task, from_dict(a.config).run.visit_samples, pa, pb, out_dir, build,
                                              embedding, points_per_panel, seed, baseline)
    return files


def _write_visitation_figure(task: str, visit_samples: int, pa: str, pb: str, out_dir: str, build: dict,
                             embedding: str, points_per_panel: int, seed: int, baseline: str) -> list[str]:
    with np.load(pa) as va, np.load(pb) as vb:
        groups = visitation_groups(dict(va), dict(vb))
    rng = np.random.default_rng(seed)
    groups = {k: subsample(v, points_per_panel, rng) for k, v in groups.items()}
    keys = [k for k, v in groups.items() if len(v)]
    if not keys:
        return []
    xy = embed_2d(np.concatenate([groups[k] for k in keys], 0), embedding, seed)
    parts, i = {}, 0
    for k in keys:
        parts[k] = xy[i:i + len(groups[k])]
        i += len(groups[k])
    from scipy import stats

    plt = pyplot()
    pad = 0.05 * (xy.max(0) - xy.min(0) + 1e-9)
    lo, hi = xy.min(0) - pad, xy.max(0) + pad
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], 80), np.linspace(lo[1], hi[1], 80))
    cols = {"teacher": ("teacher (Meta, independent)", "tab:red"), "student": ("student (Meta's D1)", "tab:green"),
            "ddpg": (METHOD_NAMES.get(baseline, baseline), METHOD_COLORS.get(baseline, "tab:blue"))}
    fig, axes = plt.subplots(2, 3, figsize=(11, 7), dpi=110, sharex=True, sharey=True)
    for r, when in enumerate(("early", "late")):
        for c, who in enumerate(("teacher", "student", "ddpg")):
            ax = axes[r, c]
            pts = parts.get((when, who))
            title, color = cols[who]
            ax.set_title(f"{title}, {when}", fontsize=9)
            if pts is None or len(pts) == 0:
                ax.text(0.5, 0.5, "no states stored", ha="center", va="center", transform=ax.transAxes)
                continue
            ax.scatter(pts[:, 0], pts[:, 1], s=2, alpha=0.25, color=color)
            try:
                kde = stats.gaussian_kde(pts.T)
                ax.contour(gx, gy, kde(np.vstack([gx.ravel(), gy.ravel()])).reshape(gx.shape), levels=6,
                           colors="k", linewidths=0.6)
            except (np.linalg.LinAlgError, ValueError):  # too few or degenerate points for a density
                pass
    for ax in axes[-1]:
        ax.set_xlabel(f"{embedding} 1")
    for ax in axes[:, 0]:
        ax.set_ylabel(f"{embedding} 2")
    fig.suptitle(f"State visitation on {task_name(task)}: first vs latest "
                 f"{visit_samples} states per seed ({embedding}, "
                 f"≤{points_per_panel} points per panel)", fontsize=10)
    fig.tight_layout()
    path = os.path.join(out_dir, f"visitation_{task}.png")
    save_figure(fig, path, build)
    plt.close(fig)
    return [path]
