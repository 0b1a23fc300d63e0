"""The paper's artefacts, rebuilt from stored run folders (no training here).

    python -m experiments.artefacts --runs-dir runs/reproduce --results-dir results
    python -m experiments.artefacts --preset modern --embedding pca

Reads a grid of run folders laid out as ``<runs-dir>/<preset>/<task>/<method>``
(what ``experiments.reproduce`` writes; each one an ``experiments.run`` output
folder), copies every finished one into the committed archive
``<results>/cells/<task>/<method>`` (``archive_cell``; run folders hold large
checkpoints and are not committed), reads cells without a finished run folder
from that archive, and writes, under the results folder:

* ``table2.md`` / ``table2.json`` / ``table2_per_seed.csv``: the paper's Table 2
  (rows = tasks, columns = methods): final evaluation return mean ± std over
  seeds, the 95% t confidence interval, Welch's t-test of Meta (independent)
  vs DDPG (parameter noise), the budget and the number of seeds run, next to
  the paper's numbers;
* ``curves_<task>.png``: learning curves, mean ± std band per method (Figure 3);
* ``steps_to_threshold.csv`` / ``.md``: the first env step at which each
  method's seed-mean evaluation return reaches the best seed-mean value of the
  DDPG (parameter noise) baseline, and the ratio to DDPG's own step (the
  paper's "about 1/6 of the samples" claim);
* ``comparisons.md`` / ``.json``: every method against every other per task (medians, ranges, best
  seed means, differences, Welch p, at how many evaluations one seed-mean curve is above the other):
  the numbers the README's prose quotes beyond Table 2;
* ``teacher_designs_idp.png``: independent vs variance teacher vs DDPG on
  InvertedDoublePendulum (Figure 2);
* ``visitation_<task>.png``: states visited by the teacher, the student and
  DDPG, early and late, jointly embedded in 2-D with density contours (Figure 4,
  InvertedDoublePendulum in the paper), for every task whose two cells stored them;
* ``README.md`` (what is there and how it was made) and ``manifest.json``
  (provenance: commit, machine, and per cell its config, seeds, budget, wall time).

Every number comes from the stored results; cells without a finished run are
shown as "not run" (or "incomplete"), never estimated.

Definitions (also written into the files):

* a seed's *final* return is the mean of its last ``max(1, floor(T / 10))``
  evaluations, T the number of evaluations it has (each evaluation is itself the
  mean return of ``run.eval_episodes`` deterministic episodes);
* ± is the sample standard deviation over seeds (ddof=1);
* the 95% CI is mean ± t(0.975, n-1) · s / sqrt(n) over the n seeds' final returns;
* the p-value is the two-sided Welch t-test (``scipy.stats.ttest_ind(equal_var=False)``).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import datetime
import glob
import json
import math
import os
import sys
from typing import Iterable, Sequence

import numpy as np

from metapg_jax import reporting

# ---------------------------------------------------------------------------------------------- grid

# In the paper's Table 2 order.
TASKS = ("inverted_double_pendulum", "inverted_pendulum", "hopper", "pendulum", "halfcheetah", "reacher")
TASK_NAMES = {"pendulum": "Pendulum", "inverted_pendulum": "InvertedPendulum",
              "inverted_double_pendulum": "InvertedDoublePendulum", "hopper": "Hopper",
              "halfcheetah": "HalfCheetah", "reacher": "Reacher"}
# Grid method name -> experiments.run options.
METHODS = {
    "meta-independent": ["--method=meta", "--teacher=independent"],
    "meta-variance": ["--method=meta", "--teacher=variance"],
    "ddpg-paramnoise": ["--method=ddpg", "--noise=adaptive-param"],
    "ddpg-normal": ["--method=ddpg", "--noise=normal"],
}
METHOD_NAMES = {"meta-independent": "Meta (independent)", "meta-variance": "Meta (variance)",
                "ddpg-paramnoise": "DDPG (param noise)", "ddpg-normal": "DDPG (normal noise)"}
METHOD_COLORS = {"meta-independent": "tab:red", "meta-variance": "tab:orange",
                 "ddpg-paramnoise": "tab:blue", "ddpg-normal": "tab:cyan"}
META, BASELINE = "meta-independent", "ddpg-paramnoise"
# The DDPG each preset's Meta is compared against: the paper's baseline (adaptive parameter noise), and
# for the modern preset its own exploration (Gaussian action noise 0.1, see metapg_jax/config.py).
BASELINES = {"paper": BASELINE, "modern": "ddpg-normal"}


def baseline_for(preset: str) -> str:
    """Grid method name of the DDPG baseline of ``preset``'s comparisons (Welch test, thresholds, figures)."""
    if preset not in BASELINES:
        raise ValueError(f"unknown preset {preset!r}; valid presets: {', '.join(BASELINES)}")
    return BASELINES[preset]

# The paper's Table 2 (Xu et al., 2018): final return mean ± std, Meta vs DDPG; 3 seeds, gym v1 tasks.
PAPER_TABLE2 = {
    "inverted_double_pendulum": {"meta": (7718.0, 277.0), "ddpg": (2795.0, 1325.0)},
    "inverted_pendulum": {"meta": (745.0, 27.0), "ddpg": (499.0, 23.0)},
    "hopper": {"meta": (205.0, 41.0), "ddpg": (135.0, 42.0)},
    "pendulum": {"meta": (-123.0, 10.0), "ddpg": (-206.0, 31.0)},
    "halfcheetah": {"meta": (2011.0, 339.0), "ddpg": (1594.0, 298.0)},
    "reacher": {"meta": (-12.16, 1.19), "ddpg": (-11.67, 3.39)},
}
PAPER_SEEDS = 3

FINAL_DEFINITION = ("final return of a seed = mean of its last max(1, floor(T/10)) evaluations (the last 10% "
                    "of its T evaluations, at least 1); each evaluation is the mean return of `run.eval_episodes` "
                    "deterministic episodes of the student")
STATS_DEFINITION = ("mean ± std: over seeds, sample std (ddof=1); 95% CI: mean ± t(0.975, n-1)·s/√n (Student t "
                    "over the n seeds); p: two-sided Welch t-test (scipy.stats.ttest_ind, equal_var=False) of the "
                    "seeds' final returns, Meta (independent) vs {baseline}")


def stats_definition(baseline: str = BASELINE) -> str:
    return STATS_DEFINITION.format(baseline=METHOD_NAMES.get(baseline, baseline))


# ---------------------------------------------------------------------------------------------- statistics
# Small pure functions on NumPy arrays (unit-tested against hand-written formulas).

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


# ---------------------------------------------------------------------------------------------- loading

@dataclasses.dataclass
class RunResult:
    """One grid cell's stored results (a run folder, finished or not)."""

    task: str
    method: str
    path: str
    complete: bool            # summary.json exists (the run finished)
    config: dict              # config.json's "config"
    run_args: dict            # config.json's "run_args"
    info: dict                # the rest of config.json (jax version, backend, devices)
    summary: dict             # summary.json ({} while running)
    provenance: dict          # reproduce.json ({} for runs not started by experiments.reproduce)
    steps: np.ndarray         # (T,) env steps of the evaluations
    values: np.ndarray        # (seeds, T) evaluation returns
    train_seconds: float | None = None  # training time over all calls, from metrics.jsonl (reporting.training_seconds)
    train_seconds_exact: bool = False

    @property
    def num_seeds(self) -> int:
        return int(self.values.shape[0])

    @property
    def budget(self) -> int:
        return int(self.config["run"]["total_steps"])

    @property
    def env_steps_done(self) -> int:
        return int(self.steps[-1]) if self.steps.size else 0

    def final(self) -> np.ndarray:
        return final_returns(self.values)


def load_run(path: str, task: str = "", method: str = "") -> RunResult | None:
    """A run folder's results, or None when it has no evaluations yet."""
    from metapg_jax import reporting

    cfg_path, metrics_path = os.path.join(path, "config.json"), os.path.join(path, "metrics.jsonl")
    if not (os.path.exists(cfg_path) and os.path.exists(metrics_path)):
        return None
    with open(cfg_path) as f:
        stored = json.load(f)
    rows = reporting.read_jsonl(metrics_path)
    if not rows:
        return None
    steps, values = reporting.curves(rows)
    train_s, exact = reporting.training_seconds(rows)
    summary = read_json(os.path.join(path, "summary.json"))
    info = {k: v for k, v in stored.items() if k not in ("config", "run_args")}
    return RunResult(task=task or stored["config"]["env"]["name"], method=method, path=path,
                     complete=bool(summary), config=stored["config"], run_args=stored["run_args"], info=info,
                     summary=summary, provenance=read_json(os.path.join(path, "reproduce.json")),
                     steps=np.asarray(steps), values=np.asarray(values, np.float64),
                     train_seconds=None if train_s is None else round(train_s, 2), train_seconds_exact=exact)


def read_json(path: str) -> dict:
    """The JSON object stored at ``path``; {} when the file does not exist."""
    if not os.path.exists(path):
        return {}
    with open(path) as f:
        return json.load(f)


def collect(preset_dir: str, tasks: Iterable[str] = TASKS, methods: Iterable[str] = METHODS,
            archive_dir: str | None = None) -> dict:
    """{(task, method): RunResult} for the cells of ``<preset_dir>/<task>/<method>`` that have evaluations.

    With ``archive_dir`` (the committed copies, see ``archive_cell``), a cell that has no finished run
    under ``preset_dir`` is read from ``<archive_dir>/<task>/<method>`` when a finished one is archived
    there: run folders are not committed, so a fresh clone has only the archive."""
    out = {}
    for task in tasks:
        for method in methods:
            r = load_run(os.path.join(preset_dir, task, method), task, method)
            if archive_dir is not None and (r is None or not r.complete):
                a = load_run(os.path.join(archive_dir, task, method), task, method)
                if a is not None and a.complete:
                    r = a
            if r is not None:
                out[(task, method)] = r
    return out


# What a finished cell keeps in the committed archive (``<results>/cells/<task>/<method>``): everything the
# artefacts read. Model checkpoints and the run's own PNGs stay in the run folder (gitignored).
ARCHIVE_FILES = ("config.json", "metrics.jsonl", "summary.json", "reproduce.json")
# visits.npz (the state-visitation sample) is kept for the two methods the figure compares, thinned to
# this many states per seed and array (evenly spaced; the figure draws <= 500 points per panel).
ARCHIVE_VISITS_PER_SEED = 250


def archive_dir_for(results_dir: str, preset: str) -> str:
    return os.path.join(results_dir_for(results_dir, preset), "cells")


def copy_result_files(run_path: str, archive_path: str) -> None:
    """Copies the ``ARCHIVE_FILES`` a run folder has into ``archive_path``, each atomically."""
    import shutil

    os.makedirs(archive_path, exist_ok=True)
    for name in ARCHIVE_FILES:
        src = os.path.join(run_path, name)
        if os.path.exists(src):
            tmp = os.path.join(archive_path, name + ".tmp")
            shutil.copyfile(src, tmp)
            os.replace(tmp, os.path.join(archive_path, name))


def archive_cell(run_path: str, archive_path: str, method: str, baseline: str = BASELINE) -> bool:
    """Copies a finished run folder's results into the archive (atomically, file by file); False if the
    run is not finished. Re-archiving a cell replaces its files. The visitation sample is kept for the
    methods of the visitation figure only (Meta independent and ``baseline``)."""
    if not os.path.exists(os.path.join(run_path, "summary.json")):
        return False
    copy_result_files(run_path, archive_path)
    visits = os.path.join(run_path, "visits.npz")
    if method in (META, baseline) and os.path.exists(visits):
        with np.load(visits) as v:
            thinned = {}
            for k, x in v.items():
                if x.ndim >= 2 and x.shape[-2] > ARCHIVE_VISITS_PER_SEED:  # (..., states, obs)
                    idx = np.linspace(0, x.shape[-2] - 1, ARCHIVE_VISITS_PER_SEED).round().astype(int)
                    x = np.take(x, idx, axis=-2)
                thinned[k] = x
        reporting.savez_atomic(os.path.join(archive_path, "visits.npz"), thinned)
    return True


# ---------------------------------------------------------------------------------------------- provenance

def cell_provenance(r: RunResult) -> dict:
    """What a result cell was made from: commit, config, seeds, budget, machine, wall time.

    ``wall_seconds`` is reproduce.json's (the recorded calls, compile included) or else the run's own
    summary; ``train_seconds_all_calls`` adds up the training time of every call from the metrics rows."""
    prov = r.provenance
    wall = prov.get("wall_seconds")
    if wall is None and r.summary:
        wall = (r.summary.get("compile_seconds") or 0) + (r.summary.get("train_seconds") or 0)
    return {
        "task": r.task, "method": r.method, "path": r.path, "complete": r.complete,
        "commit": prov.get("commit"), "seeds": r.num_seeds, "base_seed": r.run_args.get("seed"),
        "budget_env_steps": r.budget, "env_steps_done": r.env_steps_done, "evaluations": int(r.steps.size),
        "preset": r.config.get("preset"), "run_args": r.run_args, "config": r.config,
        "machine": prov.get("machine") or {k: r.info.get(k) for k in ("jax_version", "backend", "devices")},
        "wall_seconds": wall,
        # every call's training time, compile excluded, from the metrics rows: also the calls a session end
        # killed before reproduce.json recorded them (which wall_seconds misses)
        "train_seconds_all_calls": r.train_seconds, "train_seconds_all_calls_exact": r.train_seconds_exact,
    }


def provenance_footer(build: dict, cells: Iterable[RunResult]) -> str:
    """Markdown lines: commit and machine of this build and of the runs used."""
    cells = list(cells)
    commits = sorted({commit for c in cells
                      for commit in (c.provenance.get("commits") or [c.provenance.get("commit") or "unknown"])})
    lines = ["", "---", "",
             f"Built {build['built']} from `{build['runs_dir']}` at commit `{build['commit'] or 'unknown'}`"
             f"{' (uncommitted changes)' if build.get('dirty') else ''} on {build['machine']['platform']} "
             f"({build['machine']['cpu_count']} CPUs). Runs used: {len(cells)}"
             + (f", made at commit(s) {', '.join(f'`{c}`' for c in commits)}" if cells else "")
             + ". Per-cell config, seeds, budget, machine and wall time: `manifest.json`."]
    return "\n".join(lines) + "\n"


def build_info(runs_dir: str) -> dict:
    return {"built": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
            "runs_dir": runs_dir, **reporting.provenance()}


# ---------------------------------------------------------------------------------------------- Table 2

def table2_rows(results: dict, tasks: Sequence[str], methods: Sequence[str], baseline: str = BASELINE) -> list[dict]:
    """One dict per task with, per method, the statistics of the finished runs (None: not run / incomplete)."""
    rows = []
    for task in tasks:
        row = {"task": task, "methods": {}, "paper": PAPER_TABLE2.get(task)}
        for method in methods:
            r = results.get((task, method))
            if r is None:
                row["methods"][method] = {"status": "not run"}
                continue
            if not r.complete:
                row["methods"][method] = {"status": "incomplete", "env_steps_done": r.env_steps_done,
                                          "budget": r.budget}
                continue
            final = r.final()
            mean, std = mean_std(final)
            _, half = t_interval(final)
            row["methods"][method] = {
                "status": "done", "mean": mean, "std": std, "ci95_half_width": half,
                "ci95": [mean - half, mean + half] if math.isfinite(half) else None,
                "n": int(final.size), "budget": r.budget, "env_steps": r.env_steps_done,
                "final_evaluations": num_final_evaluations(r.steps.size), "evaluations": int(r.steps.size),
                "base_seed": r.run_args.get("seed"), "per_seed": [float(v) for v in final],
                "run_commit": r.provenance.get("commit"), "backend": r.info.get("backend"),
                "wall_seconds": cell_provenance(r)["wall_seconds"], "run_dir": r.path}
        a, b = row["methods"].get(META, {}), row["methods"].get(baseline, {})
        row["welch"] = None
        if a.get("status") == "done" and b.get("status") == "done":
            if a["budget"] == b["budget"]:  # never a test between cells of different budgets (mid-extension)
                t, p = welch_test(a["per_seed"], b["per_seed"])
                row["welch"] = {"t": t, "p": p, "difference": a["mean"] - b["mean"]}
            else:
                row["welch_skipped"] = "budgets differ"
        rows.append(row)
    return rows


def _cell_text(cell: dict) -> str:
    if cell["status"] == "not run":
        return "not run"
    if cell["status"] == "incomplete":
        return f"incomplete ({cell['env_steps_done']:,} of {cell['budget']:,} steps)"
    return f"{fmt(cell['mean'])} ± {fmt(cell['std'])}"


def _ci_text(cell: dict) -> str:
    if cell["status"] != "done":
        return cell["status"] if cell["status"] == "not run" else "incomplete"
    if cell["ci95"] is None:
        return f"{fmt(cell['mean'])} (n={cell['n']}, no CI)"
    lo, hi = cell["ci95"]
    return f"[{fmt(lo)}, {fmt(hi)}] (n={cell['n']})"


def _joined(values: dict) -> str:
    """One value, or 'method: value' pairs when the methods differ."""
    distinct = sorted(set(values.values()))
    if not distinct:
        return "—"
    if len(distinct) == 1:
        return f"{distinct[0]:,}"
    return "; ".join(f"{METHOD_NAMES.get(m, m)}: {v:,}" for m, v in values.items())


def _budget_text(task: str, budgets: dict) -> str:
    """The budget column: ``_joined`` budgets, flagged when a cell ran fewer steps than the paper's budget
    (``envs.default_budget``: the paper's, rounded down to whole evaluation intervals), so that a
    reduced-budget row is never read against the paper's full-budget numbers unmarked."""
    from envs import default_budget, get_spec  # brax on import: only when a table is written

    text = _joined(budgets)
    if task in PAPER_TABLE2 and budgets and min(budgets.values()) < default_budget(task):
        text += f" (reduced; paper: {get_spec(task).paper_budget:,})"
    return text


def engines_text(results: Iterable["RunResult"]) -> str:
    """How the stored MuJoCo cells were stepped: 'MJX', "MuJoCo's C engine" or both (pendulum is JAX)."""
    physics = {r.config["env"].get("physics", "mjx") for r in results if r.task != "pendulum"}
    names = {"mjx": "MJX", "mujoco": "MuJoCo's C engine"}
    return " and ".join(names[p] for p in sorted(physics)) if physics else "MJX"


def write_table2(rows: list[dict], methods: Sequence[str], out_dir: str, footer: str, preset: str,
                 build_commit: str | None = None, engines: str = "MJX") -> list[str]:
    """table2.md, table2.json and table2_per_seed.csv from ``table2_rows``; returns the paths."""
    os.makedirs(out_dir, exist_ok=True)
    names = [METHOD_NAMES.get(m, m) for m in methods]
    baseline = baseline_for(preset)
    protocol = ("" if preset == "paper" else
                f" The paper's numbers are for its own protocol (the paper preset's networks, noise and budgets), "
                f"not for the {preset} preset: they are there for scale only.")
    md = [f"# Table 2: final evaluation return ({preset} preset)", "",
          f"Rows: tasks; columns: methods, mean ± std over the seeds run here, next to the paper's Table 2 "
          f"(Meta / DDPG; {PAPER_SEEDS} seeds, gym v1 tasks, so not directly comparable: our tasks are gymnasium "
          f"v5 models on {engines}). \"not run\": no finished run is stored for that cell (nothing is estimated); "
          f"\"reduced\" in the budget column: fewer env steps per seed than the paper's budget."
          + protocol, "",
          f"- {FINAL_DEFINITION}.", f"- {stats_definition(baseline)}.", "",
          "| task | " + " | ".join(names) + " | paper Meta | paper DDPG | budget (env steps / seed) | seeds run |",
          "|---|" + "---|" * len(names) + "---|---|---|---|"]
    for row in rows:
        cells = [_cell_text(row["methods"][m]) for m in methods]
        paper = row["paper"]
        pm = f"{paper['meta'][0]:,g} ± {paper['meta'][1]:,g}" if paper else "—"  # as printed in the paper
        pd = f"{paper['ddpg'][0]:,g} ± {paper['ddpg'][1]:,g}" if paper else "—"
        done = {m: c for m, c in row["methods"].items() if c["status"] == "done"}
        budget = _budget_text(row["task"], {m: c["budget"] for m, c in done.items()})
        seeds = _joined({m: c["n"] for m, c in done.items()})
        md.append(f"| {TASK_NAMES.get(row['task'], row['task'])} | " + " | ".join(cells) +
                  f" | {pm} | {pd} | {budget} | {seeds} |")
    md += ["", "## 95% confidence intervals and Welch's t-test", "",
           "| task | " + " | ".join(names) + f" | Meta (ind.) − {METHOD_NAMES.get(baseline, baseline)} | Welch t | p |",
           "|---|" + "---|" * len(names) + "---|---|---|"]
    for row in rows:
        w = row["welch"]
        na = f"n/a ({row['welch_skipped']})" if row.get("welch_skipped") else "n/a"
        tail = (f"{fmt(w['difference'])} | {fmt(w['t'], 2)} | {fmt_p(w['p'])}" if w else f"{na} | n/a | n/a")
        md.append(f"| {TASK_NAMES.get(row['task'], row['task'])} | " +
                  " | ".join(_ci_text(row["methods"][m]) for m in methods) + f" | {tail} |")
    md.append(footer)
    paths = [os.path.join(out_dir, n) for n in ("table2.md", "table2.json", "table2_per_seed.csv")]
    with open(paths[0], "w") as f:
        f.write("\n".join(md))
    with open(paths[1], "w") as f:
        json.dump({"preset": preset, "baseline": baseline, "final_definition": FINAL_DEFINITION,
                   "statistics": stats_definition(baseline),
                   "paper_seeds": PAPER_SEEDS, "rows": rows}, f, indent=2, default=_json_default)
    with open(paths[2], "w", newline="") as f:
        w = csv.writer(f)
        # seed_index i is the run's seed i: PRNG key fold_in(PRNGKey(base_seed), i).
        w.writerow(["task", "method", "seed_index", "final_return", "final_evaluations", "evaluations",
                    "env_steps", "budget", "base_seed", "run_commit", "backend", "run_wall_seconds", "run_dir",
                    "build_commit"])
        for row in rows:
            for m in methods:
                c = row["methods"][m]
                if c["status"] != "done":
                    continue
                for i, v in enumerate(c["per_seed"]):
                    w.writerow([row["task"], m, i, repr(v), c["final_evaluations"], c["evaluations"],
                                c["env_steps"], c["budget"], c["base_seed"], c["run_commit"] or "", c["backend"] or "",
                                "" if c["wall_seconds"] is None else c["wall_seconds"], c["run_dir"],
                                build_commit or ""])
    return paths


def _json_default(x):
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(type(x))


# ---------------------------------------------------------------------------------------------- curves

def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: str, build: dict) -> None:
    """Saves a PNG with the build's commit and time in its metadata."""
    fig.savefig(path, metadata={"Software": f"metapg-jax commit {build.get('commit') or 'unknown'}",
                                "Creation Time": build.get("built", "")})


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
                 preset: str) -> list[str]:
    """``curves_<task>.png`` per task with stored runs: mean ± std band over seeds per method (Figure 3)."""
    plt = _plt()
    paths = []
    for task in tasks:
        if not any((task, m) in results for m in methods):
            continue
        fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=120)
        _plot_methods(ax, results, task, methods)
        ax.set_title(f"{TASK_NAMES.get(task, task)} ({preset} preset): mean ± std over seeds", fontsize=10)
        fig.tight_layout()
        path = os.path.join(out_dir, f"curves_{task}.png")
        _save(fig, path, build)
        plt.close(fig)
        paths.append(path)
    return paths


def write_teacher_designs(results: dict, out_dir: str, build: dict, preset: str,
                          task: str = "inverted_double_pendulum") -> list[str]:
    """Independent vs variance teacher vs the preset's DDPG baseline, curves on one task (Figure 2)."""
    methods = ("meta-independent", "meta-variance", baseline_for(preset))
    if not any((task, m) in results for m in methods):
        return []
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=120)
    _plot_methods(ax, results, task, methods)
    ax.set_title(f"Teacher designs on {TASK_NAMES.get(task, task)} ({preset} preset)", fontsize=10)
    fig.tight_layout()
    short = "idp" if task == "inverted_double_pendulum" else task
    path = os.path.join(out_dir, f"teacher_designs_{short}.png")
    _save(fig, path, build)
    plt.close(fig)
    return [path]


# ---------------------------------------------------------------------------------------------- steps to threshold

def steps_to_threshold_rows(results: dict, tasks: Sequence[str], methods: Sequence[str],
                            baseline: str = BASELINE) -> list[dict]:
    """Per task and method: first env step where the seed-mean curve reaches the DDPG baseline's best seed mean."""
    rows = []
    for task in tasks:
        base = results.get((task, baseline))
        if base is None:
            continue
        base_mean = np.nanmean(base.values, 0)
        threshold = float(np.nanmax(base_mean))
        base_step = first_step_reaching(base.steps, base_mean, threshold)
        for m in methods:
            r = results.get((task, m))
            if r is None:
                continue
            step = first_step_reaching(r.steps, np.nanmean(r.values, 0), threshold)
            rows.append({"task": task, "method": m, "threshold": threshold, "baseline_step": base_step,
                         "step": step, "ratio": (step / base_step) if step is not None and base_step else None,
                         "seeds": r.num_seeds, "env_steps_run": r.env_steps_done, "complete": r.complete,
                         "baseline_complete": base.complete})
    return rows


def write_steps_to_threshold(rows: list[dict], out_dir: str, footer: str, preset: str,
                             build_commit: str | None = None) -> list[str]:
    paths = [os.path.join(out_dir, "steps_to_threshold.csv"), os.path.join(out_dir, "steps_to_threshold.md")]
    keys = ["task", "method", "threshold", "baseline_step", "step", "ratio", "seeds", "env_steps_run", "complete",
            "baseline_complete"]
    with open(paths[0], "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys + ["build_commit"])
        w.writeheader()
        for row in rows:
            w.writerow({**{k: ("" if row[k] is None else row[k]) for k in keys}, "build_commit": build_commit or ""})
    baseline = METHOD_NAMES.get(baseline_for(preset), baseline_for(preset))
    md = [f"# Samples to reach the DDPG baseline's best ({preset} preset)", "",
          f"Threshold: the best value over evaluations of the {baseline} seed-mean evaluation-return curve. "
          "`step`: the first evaluation's env step at which a method's seed-mean curve reaches it; "
          "`ratio` = step / DDPG's own step (the paper: Meta needs about 1/6 of DDPG's samples on "
          "InvertedDoublePendulum). \"not reached\": never within the env steps run.", "",
          "| task | method | threshold | step | DDPG step | ratio | env steps run | seeds |",
          "|---|---|---|---|---|---|---|---|"]
    for row in rows:
        step = "not reached" if row["step"] is None else f"{row['step']:,}"
        bstep = "n/a" if row["baseline_step"] is None else f"{row['baseline_step']:,}"
        run = f"{row['env_steps_run']:,}" + ("" if row["complete"] else " (incomplete)")
        ratio = "n/a" if row["ratio"] is None else f"{row['ratio']:.3f}"
        md.append(f"| {TASK_NAMES.get(row['task'], row['task'])} | {METHOD_NAMES.get(row['method'], row['method'])} "
                  f"| {fmt(row['threshold'])} | {step} | {bstep} | {ratio} | {run} | {row['seeds']} |")
    if not rows:
        md.append(f"| (no task has a {baseline} run) | | | | | | | |")
    md.append(footer)
    with open(paths[1], "w") as f:
        f.write("\n".join(md))
    return paths


# ---------------------------------------------------------------------------------------------- comparisons

def comparison_rows(results: dict, tasks: Sequence[str], methods: Sequence[str]) -> dict:
    """Every method against every other, per task: the numbers the README's prose quotes.

    ``{"methods": [...], "pairs": [...]}``. Per finished cell: median, min and max of the seeds' final
    returns, the best value of the seed-mean curve and its step, the mean of the seed-mean curve over all
    evaluations. Per pair (a, b) of finished cells with the same budget (in ``methods`` order): the
    difference of mean finals a − b, Welch's t and p, and at how many of their common evaluation steps the
    seed-mean curve of a is above b's, and b's above a's."""
    per_method, pairs = [], []
    for task in tasks:
        done = [m for m in methods if (task, m) in results and results[(task, m)].complete]
        finals = {m: results[(task, m)].final() for m in done}
        curves = {m: np.nanmean(results[(task, m)].values, 0) for m in done}  # seed-mean curves
        for m in done:
            r, final, curve = results[(task, m)], finals[m], curves[m]
            best = int(np.nanargmax(curve))
            per_method.append({"task": task, "method": m, "n": int(final.size), "budget": r.budget,
                               "mean": float(final.mean()), "median": float(np.median(final)),
                               "min": float(final.min()), "max": float(final.max()),
                               "best_seed_mean": float(curve[best]), "best_seed_mean_step": int(r.steps[best]),
                               "mean_over_evaluations": float(np.nanmean(curve)), "evaluations": int(r.steps.size)})
        for i, a in enumerate(done):
            for b in done[i + 1:]:
                ra, rb = results[(task, a)], results[(task, b)]
                if ra.budget != rb.budget:
                    continue  # mid-extension: never compared across budgets (as table2_rows)
                t, p = welch_test(finals[a], finals[b])
                common, ia, ib = np.intersect1d(ra.steps, rb.steps, return_indices=True)
                ca, cb = curves[a][ia], curves[b][ib]
                pairs.append({"task": task, "a": a, "b": b, "budget": ra.budget,
                              "difference": float(finals[a].mean() - finals[b].mean()), "t": t, "p": p,
                              "a_above_b": int((ca > cb).sum()), "b_above_a": int((cb > ca).sum()),
                              "common_evaluations": int(common.size)})
    return {"methods": per_method, "pairs": pairs}


def write_comparisons(comparisons: dict, out_dir: str, footer: str, preset: str,
                      build_commit: str | None = None) -> list[str]:
    """comparisons.md and comparisons.json from ``comparison_rows``; returns the paths."""
    paths = [os.path.join(out_dir, "comparisons.md"), os.path.join(out_dir, "comparisons.json")]
    name = lambda m: METHOD_NAMES.get(m, m)
    md = [f"# Every method against every other ({preset} preset)", "",
          "The numbers the README's prose quotes beyond `table2.md`, all from the same stored cells (finished "
          "cells only; pairs only between cells of the same budget).", "",
          f"- {FINAL_DEFINITION}.",
          "- best seed mean: the highest value of the seed-mean evaluation curve, and the env step of that "
          "evaluation; mean over evaluations: the seed-mean curve averaged over all its evaluations.",
          "- a − b: difference of the mean final returns; p: two-sided Welch t-test of the seeds' final returns; "
          "a above b (b above a): at how many of the evaluation steps both cells have the seed-mean curve of a "
          "is strictly above b's (b's above a's)."]
    for task in dict.fromkeys(r["task"] for r in comparisons["methods"]):
        md += ["", f"## {TASK_NAMES.get(task, task)}", "",
               "| method | seeds | budget | mean final | median | min | max | best seed mean (step) | "
               "mean over evaluations |", "|---|---|---|---|---|---|---|---|---|"]
        for r in (r for r in comparisons["methods"] if r["task"] == task):
            md.append(f"| {name(r['method'])} | {r['n']} | {r['budget']:,} | {fmt(r['mean'])} | {fmt(r['median'])} "
                      f"| {fmt(r['min'])} | {fmt(r['max'])} | {fmt(r['best_seed_mean'])} "
                      f"({r['best_seed_mean_step']:,}) | {fmt(r['mean_over_evaluations'])} |")
        pairs = [p for p in comparisons["pairs"] if p["task"] == task]
        if pairs:
            md += ["", "| a | b | a − b | Welch t | p | a above b | b above a |", "|---|---|---|---|---|---|---|"]
            for p in pairs:
                md.append(f"| {name(p['a'])} | {name(p['b'])} | {fmt(p['difference'])} | {fmt(p['t'], 2)} | "
                          f"{fmt_p(p['p'])} | {p['a_above_b']} of {p['common_evaluations']} | "
                          f"{p['b_above_a']} of {p['common_evaluations']} |")
    if not comparisons["methods"]:
        md += ["", "(no finished cell is stored)"]
    md.append(footer)
    with open(paths[0], "w") as f:
        f.write("\n".join(md))
    with open(paths[1], "w") as f:
        json.dump({"preset": preset, "final_definition": FINAL_DEFINITION, "build_commit": build_commit,
                   **comparisons}, f, indent=2, default=_json_default)
    return paths


# ---------------------------------------------------------------------------------------------- visitation

def visitation_groups(teacher_visits: dict, ddpg_visits: dict) -> dict:
    """{(row, col): states (n, obs)} for the 2x3 figure: rows early/late, cols teacher/student/DDPG.

    Takes the valid rows of each seed (``min(count, K)``; the ``*_late`` ring is
    in arbitrary order, which does not matter for a density) and pools the seeds.
    """
    def valid(v: dict, prefix: str, when: str) -> np.ndarray:
        arr = np.asarray(v[f"{prefix}_{when}"], np.float64)      # (seeds, K, obs)
        counts = np.asarray(v[f"{prefix}_count"]).reshape(-1)
        k = arr.shape[1]
        parts = [arr[i, :min(int(counts[i]), k)] for i in range(arr.shape[0])]
        return np.concatenate(parts, 0) if parts else np.zeros((0, arr.shape[-1]))

    groups = {}
    for when in ("early", "late"):
        groups[(when, "teacher")] = valid(teacher_visits, "explore", when)
        groups[(when, "student")] = valid(teacher_visits, "student", when)
        groups[(when, "ddpg")] = valid(ddpg_visits, "explore", when)
    return groups


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


def write_visitation(results: dict, out_dir: str, build: dict, tasks: Sequence[str] = TASKS,
                     embedding: str = "tsne", points_per_panel: int = 500, seed: int = 0,
                     baseline: str = BASELINE) -> list[str]:
    """``visitation_<task>.png`` for each of ``tasks`` whose Meta (independent) and DDPG (``baseline``) cells
    both stored ``visits.npz``: teacher / student and DDPG states, early and late, jointly embedded in 2-D,
    with Gaussian-KDE contours (the paper's Figure 4, on InvertedDoublePendulum there)."""
    files = []
    for task in tasks:
        a, b = results.get((task, META)), results.get((task, baseline))
        if a is None or b is None:
            continue
        pa, pb = os.path.join(a.path, "visits.npz"), os.path.join(b.path, "visits.npz")
        if os.path.exists(pa) and os.path.exists(pb):
            files += _write_visitation_figure(task, a.config["meta"]["visit_samples"], pa, pb, out_dir, build,
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

    plt = _plt()
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
    fig.suptitle(f"State visitation on {TASK_NAMES.get(task, task)}: first vs latest "
                 f"{visit_samples} states per seed ({embedding}, "
                 f"≤{points_per_panel} points per panel)", fontsize=10)
    fig.tight_layout()
    path = os.path.join(out_dir, f"visitation_{task}.png")
    _save(fig, path, build)
    plt.close(fig)
    return [path]


# ---------------------------------------------------------------------------------------------- all

def results_dir_for(results_dir: str, preset: str) -> str:
    """The paper preset's artefacts go to ``results_dir``; another preset's to ``results_dir/<preset>``."""
    return results_dir if preset == "paper" else os.path.join(results_dir, preset)


def build_all(runs_dir: str, results_dir: str, preset: str = "paper", tasks: Sequence[str] = TASKS,
              methods: Sequence[str] = tuple(METHODS), embedding: str = "tsne", visitation_tasks: Sequence[str] | None = None,
              points_per_panel: int = 500, extra_provenance: dict | None = None) -> dict:
    """Rebuilds every artefact from ``<runs_dir>/<preset>/<task>/<method>``; returns the manifest.

    Finished run folders are first copied into the committed archive ``<results>/cells/<task>/<method>``
    (``archive_cell``); cells without a finished run folder are read from there."""
    out_dir = results_dir_for(results_dir, preset)
    os.makedirs(out_dir, exist_ok=True)
    archive = archive_dir_for(results_dir, preset)
    baseline = baseline_for(preset)
    for task in tasks:  # every finished run folder is (re)archived before anything is read
        for method in methods:
            archive_cell(os.path.join(runs_dir, preset, task, method), os.path.join(archive, task, method), method,
                         baseline)
    results = collect(os.path.join(runs_dir, preset), tasks, methods, archive_dir=archive)
    build = build_info(runs_dir)
    build["preset"] = preset
    if extra_provenance:
        build.update(extra_provenance)
    footer = provenance_footer(build, results.values())
    rows = table2_rows(results, tasks, methods, baseline)
    files = write_table2(rows, methods, out_dir, footer, preset, build["commit"], engines_text(results.values()))
    files += write_curves(results, tasks, methods, out_dir, build, preset)
    files += write_steps_to_threshold(steps_to_threshold_rows(results, tasks, methods, baseline), out_dir, footer, preset,
                                      build["commit"])
    files += write_comparisons(comparison_rows(results, tasks, methods), out_dir, footer, preset, build["commit"])
    files += write_teacher_designs(results, out_dir, build, preset)
    for stale in glob.glob(os.path.join(out_dir, "visitation_*.png")):  # only what this build draws stays
        os.remove(stale)
    files += write_visitation(results, out_dir, build,
                              tasks if visitation_tasks is None else list(dict.fromkeys(visitation_tasks)),
                              embedding, points_per_panel, baseline=baseline)
    manifest = {"build": build, "files": [os.path.relpath(p, out_dir) for p in files] + ["README.md"],
                "cells": [cell_provenance(r) for r in results.values()],
                "not_run": [[t, m] for t in tasks for m in methods if (t, m) not in results]}
    files.append(write_readme(out_dir, manifest, rows, methods, footer))
    with open(os.path.join(out_dir, "manifest.json"), "w") as f:
        json.dump(manifest, f, indent=2, default=_json_default)
    return manifest


def write_readme(out_dir: str, manifest: dict, rows: list[dict], methods: Sequence[str], footer: str) -> str:
    """``README.md``: what each artefact is, which cells were run, and the headline numbers."""
    preset = manifest["build"]["preset"]
    baseline = METHOD_NAMES.get(baseline_for(preset), baseline_for(preset))
    cells = manifest["cells"]
    done = [c for c in cells if c["complete"]]
    have = set(manifest["files"])
    lines = [f"# Results ({preset} preset)", "",
             f"Rebuilt by `python -m experiments.reproduce --artefacts-only` (or `python -m experiments.artefacts`) "
             f"from the run folders under `{manifest['build']['runs_dir']}/{preset}/<task>/<method>` (not committed) "
             f"and, for cells without a finished run folder, the committed copies of finished cells in "
             f"`cells/<task>/<method>` (config, metrics, summary, provenance, thinned visitation sample). "
             f"{len(done)} finished and {len(cells) - len(done)} unfinished cells are stored; "
             f"{len(manifest['not_run'])} cells of the grid were not run.", "",
             "| file | content |", "|---|---|"]
    desc = {
        "table2.md": "the paper's Table 2: final return mean ± std per task and method, 95% CIs, Welch p "
                     f"(Meta (independent) vs {baseline}), budget and seeds, next to the paper's numbers",
        "table2.json": "the same, machine-readable (with per-seed final returns)",
        "table2_per_seed.csv": "per-seed final returns of every finished cell",
        "steps_to_threshold.md": "first env step at which each method's seed-mean curve reaches DDPG's best "
                                 "(and the ratio to DDPG's step)",
        "steps_to_threshold.csv": "steps-to-threshold as CSV (threshold, step, DDPG step, ratio per task and method)",
        "comparisons.md": "every method against every other per task: medians, ranges, best seed means, "
                          "differences, Welch p, at how many evaluations one seed-mean curve is above the other",
        "comparisons.json": "the same, machine-readable",
        "teacher_designs_idp.png": "Figure 2: independent vs variance teacher vs DDPG on InvertedDoublePendulum",
        "manifest.json": "provenance: commit, machine, and per cell config, seeds, budget, wall time",
    }
    for f in manifest["files"]:
        if f == "README.md":
            continue
        if f.startswith("curves_"):
            d = f"Figure 3: learning curves on {f[7:-4]}, mean ± std over seeds per method"
        elif f.startswith("visitation_"):
            d = f"Figure 4: states visited by teacher, student and DDPG, early vs late, on {f[11:-4]}"
        elif f.startswith("teacher_designs_"):
            d = desc["teacher_designs_idp.png"] if f == "teacher_designs_idp.png" else "teacher designs vs DDPG"
        else:
            d = desc.get(f, "")
        lines.append(f"| `{f}` | {d} |")
    lines.append("| `manifest.json` | " + desc["manifest.json"] + " |")
    if "teacher_designs_idp.png" not in have:
        lines += ["", "No InvertedDoublePendulum run is stored, so `teacher_designs_idp.png` (Figure 2) is not built."]
    if not any(f.startswith("visitation_") for f in have):
        lines += ["", f"No task has both a Meta (independent) and a {baseline} run with `visits.npz`, so the "
                      "state-visitation figure is not built."]
    lines += ["", "## Final return (mean ± std over seeds; see `table2.md` for definitions and CIs)", "",
              "| task | " + " | ".join(METHOD_NAMES.get(m, m) for m in methods) + " | Welch p |",
              "|---|" + "---|" * len(methods) + "---|"]
    for row in rows:
        w = row["welch"]
        lines.append(f"| {TASK_NAMES.get(row['task'], row['task'])} | " +
                     " | ".join(_cell_text(row["methods"][m]) for m in methods) +
                     f" | {fmt_p(w['p']) if w else row.get('welch_skipped', 'n/a')} |")
    lines.append(footer)
    path = os.path.join(out_dir, "README.md")
    with open(path, "w") as f:
        f.write("\n".join(lines))
    return path


def add_figure_options(p: argparse.ArgumentParser) -> None:
    """The state-visitation figure's options, shared by this module's CLI and experiments.reproduce."""
    p.add_argument("--embedding", default="tsne", choices=("tsne", "pca"),
                   help="2-D embedding of the state-visitation figure (pca is fast)")
    p.add_argument("--visitation-task", action="append", choices=TASKS, default=None,
                   help="build the state-visitation figure for this task only (repeatable; default: every task "
                        "whose Meta (independent) and DDPG baseline cells stored their visited states)")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments.artefacts",
                                description="Rebuild Table 2 and the figures from stored run folders.")
    p.add_argument("--runs-dir", default="runs/reproduce", help="grid root: <runs-dir>/<preset>/<task>/<method>")
    p.add_argument("--results-dir", default="results", help="output folder (a non-paper preset goes to <dir>/<preset>)")
    p.add_argument("--preset", default="paper", choices=("paper", "modern"))
    add_figure_options(p)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    manifest = build_all(args.runs_dir, args.results_dir, args.preset, embedding=args.embedding,
                         visitation_tasks=args.visitation_task)
    out = results_dir_for(args.results_dir, args.preset)
    print(f"wrote {len(manifest['files'])} artefacts to {out} from {len(manifest['cells'])} stored cells")
    return 0


if __name__ == "__main__":
    sys.exit(main())
