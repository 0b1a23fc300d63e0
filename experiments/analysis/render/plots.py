"""Plots drawn from stored results (host side, matplotlib Agg)."""

from __future__ import annotations

import numpy as np


def _per_seed(rows: list[dict], key: str) -> tuple[np.ndarray, np.ndarray]:
    seeds = sorted({r["seed"] for r in rows})
    by = {s: sorted((r for r in rows if r["seed"] == s), key=lambda r: r["cycle"]) for s in seeds}
    n = min(len(v) for v in by.values())
    cycles = np.array([r["cycle"] for r in by[seeds[0]][:n]])
    vals = np.array([[np.nan if r.get(key) is None else r[key] for r in by[s][:n]] for s in seeds], float)
    return cycles, vals


def _smooth(v: np.ndarray, width: int) -> np.ndarray:
    """Moving average along the last axis, NaN-aware."""
    if width <= 1:
        return v
    kernel = np.ones(width)
    num = np.apply_along_axis(lambda x: np.convolve(np.nan_to_num(x), kernel, "same"), -1, v)
    den = np.apply_along_axis(lambda x: np.convolve(np.isfinite(x).astype(float), kernel, "same"), -1, v)
    return num / np.maximum(den, 1)


def plot_cycles(rows: list[dict], panels, path: str, title: str) -> None:
    """An explorer's per-cycle curves (``cycles.jsonl``), one panel per ``(metric or metrics, title)`` of its
    ``cycle_panels`` (``metapg_jax.strategy``; the teacher's: meta reward, log-std, R_hat(pi') vs R_hat(pi),
    teacher-student distance).

    Mean over seeds (thick) with ± std band, smoothed over ~1% of the run.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    first = panels[0][0]
    cycles, _ = _per_seed(rows, first if isinstance(first, str) else first[0])
    width = max(1, len(cycles) // 100)
    ncols = 2 if len(panels) > 1 else 1
    nrows = -(-len(panels) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(5 * ncols, 3.25 * nrows), dpi=110, squeeze=False)
    for ax in axes.ravel()[len(panels):]:
        ax.set_visible(False)
    for ax, (key, label) in zip(axes.ravel(), panels):
        keys = key if isinstance(key, tuple) else (key,)
        for k, color in zip(keys, ("tab:orange", "tab:gray")):
            _, v = _per_seed(rows, k)
            v = _smooth(v, width)
            mean, std = np.nanmean(v, 0), np.nanstd(v, 0)
            ax.plot(cycles, mean, color=color, lw=1.5, label=k)
            ax.fill_between(cycles, mean - std, mean + std, color=color, alpha=0.2)
        ax.set_title(label, fontsize=9)
        ax.set_xlabel("cycle")
        ax.grid(alpha=0.3)
        if len(keys) > 1:
            ax.legend(fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_meta_rewards(panels: dict[tuple[str, str], dict[str, list[dict]]], path: str, title: str) -> None:
    """Several cells' meta reward per cycle side by side: one panel per (row, column) key (e.g. student, task),
    one line per cell in it (label -> the cell's ``cycles.jsonl`` rows): the mean over seeds of each seed's
    moving average over ~5% of its cycles, against the fraction of the run, with a dashed line at zero. A label
    has the same colour in every panel."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = list(dict.fromkeys(r for r, _ in panels))
    cols = list(dict.fromkeys(c for _, c in panels))
    labels = list(dict.fromkeys(label for cells in panels.values() for label in cells))
    colors = {label: plt.get_cmap("tab10")(i % 10) for i, label in enumerate(labels)}
    ncol = min(len(labels), 4)
    legend = 0.15 + 0.2 * -(-len(labels) // ncol)  # inches below the panels for the legend's rows
    height = 2.8 * len(rows) + legend
    fig, axes = plt.subplots(len(rows), len(cols), figsize=(3.6 * max(len(cols), 2), height), dpi=110,
                             squeeze=False)
    for (r, c), cells in panels.items():
        ax = axes[rows.index(r), cols.index(c)]
        for label, cycle_rows in cells.items():
            cycles, v = _per_seed(cycle_rows, "meta_reward")
            mean = np.nanmean(_smooth(v, max(1, len(cycles) // 20)), 0)
            ax.plot(np.arange(1, len(cycles) + 1) / len(cycles), mean, color=colors[label], lw=1.2, label=label)
        ax.axhline(0.0, color="k", lw=0.8, ls="--")
        ax.set_title(f"{r}, {c}", fontsize=9)
        ax.set_xlabel("fraction of the run", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    for r, c in ((r, c) for r in rows for c in cols if (r, c) not in panels):
        axes[rows.index(r), cols.index(c)].set_visible(False)
    handles = [plt.Line2D([], [], color=colors[label], lw=1.5) for label in labels]
    fig.legend(handles, labels, loc="lower center", ncol=ncol, fontsize=8, frameon=False)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0, legend / height, 1, 1))
    fig.savefig(path)
    plt.close(fig)


def plot_sweep(rows: list[dict], fields: list[str], path: str) -> None:
    """A sweep's final return per setting (``experiments.analysis.sweeps.summary_rows``): the mean with its 95% CI, the best
    setting starred, each setting labelled by its values of the swept ``fields``; nothing for no finished setting."""
    from experiments.analysis.render.figures import pyplot

    plt = pyplot()
    shown = [e for e in rows if "mean" in e]
    if not shown:
        return
    fig, ax = plt.subplots(figsize=(max(4.0, 0.6 * len(shown) + 2), 3.6), dpi=120)
    x = range(len(shown))
    lo = [e["mean"] - e["ci95"][0] if e.get("ci95") else 0.0 for e in shown]
    hi = [e["ci95"][1] - e["mean"] if e.get("ci95") else 0.0 for e in shown]
    ax.errorbar(x, [e["mean"] for e in shown], yerr=[lo, hi], fmt="o", capsize=3,
                color="tab:red")
    for i, e in zip(x, shown):
        if e.get("best"):
            ax.plot([i], [e["mean"]], "*", color="black", markersize=12)
    ax.set_xticks(list(x))
    ax.set_xticklabels(["\n".join(f"{v}" for v in e["values"].values()) for e in shown], fontsize=7)
    ax.set_xlabel(" / ".join(fields), fontsize=8)
    ax.set_ylabel("final return (mean, 95% CI)")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
