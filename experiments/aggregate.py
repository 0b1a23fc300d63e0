"""A grid's aggregate view over its tasks, as Agarwal et al. (NeurIPS 2021) recommend: per method the IQM, the
mean and the optimality gap of the seeds' normalised final returns with 95% stratified bootstrap intervals,
the probability that each teacher improves on each noise baseline, and performance profiles (a figure).

    python -m experiments.aggregate results/table2.json           # writes results/aggregate.{md,json} and
                                                                  # results/performance_profiles.png
    python -m experiments.aggregate results/td3/table2.json --anchors results/normalisation.json

The input is a grid's JSON twin (``experiments.analysis.tables``: per task and method the seeds' final returns); the
scores are normalised with the anchors of ``experiments.normalisation`` (0 = a uniformly random policy, 1 =
the reference). The methods are those with a finished cell on some task (the others are listed as absent);
only the tasks on which every one of them has a finished cell enter: aggregates over different task sets
would not be comparable (the tasks left out are listed). Each teacher (a method that does not explore with
noise) is compared with each noise baseline; a grid without both kinds compares every ordered pair of its
methods. The estimators, their intervals and the bootstrap's seed: ``experiments.analysis.stats``
(``AGGREGATE_DEFINITION``).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import sys

import numpy as np

from experiments.analysis import stats
from experiments.grid.methods import METHOD_NAMES, noise_methods, task_name

DEFAULT_ANCHORS = "results/normalisation.json"  # named by a report that does not record its anchors

PROFILE_TAUS = np.linspace(0.0, 2.0, 81)  # the profiles' thresholds, widened where a seed scores above 2


def profile_taus(scores: dict) -> np.ndarray:
    """The performance profiles' thresholds: ``PROFILE_TAUS``, or 0 to the highest score (up to the next
    quarter) where some seed scores above their end, so every profile reaches 0 inside the figure."""
    top = max((float(np.max(a)) for per_task in scores.values() for a in per_task if len(a)), default=0.0)
    end = max(float(PROFILE_TAUS[-1]), np.ceil(top * 4) / 4)
    return PROFILE_TAUS if end == PROFILE_TAUS[-1] else np.linspace(0.0, end, len(PROFILE_TAUS))


def grid_methods(grid: dict) -> list[str]:
    """Every method the grid's rows name, in their order."""
    return list({m: 0 for row in grid["rows"] for m in row["methods"]})


def grid_scores(grid: dict, anchors: dict[str, tuple[float, float]],
                labels: dict | None = None) -> tuple[list[str], list[str], dict, list[str]]:
    """(tasks, methods, scores, left_out): the tasks where every method has a finished cell and an anchor,
    the methods with a finished cell somewhere, {method: [normalised per-seed scores of each task]}, and the
    tasks left out with why (as the tables name tasks and methods; ``labels``: names for methods that
    ``experiments.grid.methods.METHOD_NAMES`` does not have)."""
    labels = {**METHOD_NAMES, **(labels or {})}
    methods = [m for m in grid_methods(grid)
               if any(row["methods"].get(m, {}).get("status") == "done" for row in grid["rows"])]
    tasks, left_out = [], []
    for row in grid["rows"]:
        absent = [m for m in methods if row["methods"].get(m, {}).get("status") != "done"]
        if row["task"] not in anchors:
            left_out.append(f"{task_name(row['task'])} (no normalisation anchors)")
        elif absent:
            left_out.append(f"{task_name(row['task'])} (no finished cell for "
                            f"{', '.join(labels.get(m, m) for m in absent)})")
        else:
            tasks.append(row["task"])
    rows = {row["task"]: row for row in grid["rows"]}
    scores = {m: [stats.normalise(rows[t]["methods"][m]["per_seed"], *anchors[t]) for t in tasks] for m in methods}
    return tasks, methods, scores, left_out


def report(grid: dict, anchors: dict[str, tuple[float, float]], scored=None,
           pairs: list[tuple[str, str]] | None = None) -> dict:
    """The aggregate numbers of a grid (``grid_scores``'s tasks, or ``scored``: its result), JSON-ready.
    ``pairs``: the (X, Y) whose probability of improvement is computed (default: each teacher against each noise
    baseline; every ordered pair in a grid without both kinds)."""
    tasks, methods, scores, left_out = scored or grid_scores(grid, anchors)
    if not tasks:
        raise ValueError("no task has a finished cell for every method and normalisation anchors: "
                         + "; ".join(left_out))
    absent = [m for m in grid_methods(grid) if m not in methods]
    out = {"tasks": tasks, "left_out": left_out, "absent_methods": absent, "methods": {}, "improvement": [],
           "definition": stats.AGGREGATE_DEFINITION.format(reps=stats.BOOTSTRAP_REPS, seed=stats.BOOTSTRAP_SEED),
           "anchors": {t: {"random_return": anchors[t][0], "reference_return": anchors[t][1]} for t in tasks}}
    for m in methods:
        entry = {"seeds_per_task": [int(len(s)) for s in scores[m]]}
        for name, statistic in stats.AGGREGATES.items():
            entry[name] = dict(zip(("point", "lo", "hi"), stats.aggregate_interval(scores[m], statistic)))
        out["methods"][m] = entry
    if pairs is None:
        noise = noise_methods(methods)
        teachers = [m for m in methods if m not in noise]
        pairs = [(x, y) for x in teachers for y in noise] or [(x, y) for x in methods for y in methods if x != y]
    for x, y in pairs:
        point, lo, hi = stats.probability_of_improvement(scores[x], scores[y])
        out["improvement"].append({"x": x, "y": y, "point": point, "lo": lo, "hi": hi,
                                   "per_task": stats.improvement_per_task(scores[x], scores[y])})
    return out


def _interval(e: dict) -> str:
    return f"{stats.fmt(e['point'], 2)} [{stats.fmt(e['lo'], 2)}, {stats.fmt(e['hi'], 2)}]"


def markdown(rep: dict, title: str, labels: dict | None = None) -> str:
    """aggregate.md; ``labels``: names for methods that ``experiments.grid.methods.METHOD_NAMES`` does not have."""
    labels = {**METHOD_NAMES, **(labels or {})}
    names = lambda ms: [labels.get(m, m) for m in ms]
    lines = [f"# {title}: aggregate scores over tasks", "",
             f"Tasks: {', '.join(task_name(t) for t in rep['tasks'])}"
             + (f". Left out: {'; '.join(rep['left_out'])}." if rep["left_out"] else ".")
             + (f" Methods of the grid without a finished cell: {', '.join(names(rep['absent_methods']))}."
                if rep.get("absent_methods") else ""), "",
             f"- {rep['definition']}.",
             "- anchors per task (random policy → 0, reference → 1): " + "; ".join(
                 f"{task_name(t)} {stats.fmt(a['random_return'])} → {stats.fmt(a['reference_return'])}"
                 for t, a in rep["anchors"].items()) + f" ({rep.get('built', {}).get('anchors') or DEFAULT_ANCHORS}).",
             *(["- a method with no cell of its own on a task is scored with the cell it equals there: " + "; ".join(
                 f"{task_name(k.split('/')[0])} {labels.get(k.split('/')[1], k.split('/')[1])} = "
                 f"{labels.get(v, v)}" for k, v in rep["standing_for"].items()) + "."] if rep.get("standing_for") else []),
             *([f"- left out (not finished on every task): {', '.join(names(rep['variants_not_on_every_task']))}."]
               if rep.get("variants_not_on_every_task") else []),
             *(f"- {note}" for note in rep.get("notes", [])),
             *([f"- built {rep['built']['date']} at commit {rep['built']['commit'][:7]}"
                + (" (uncommitted changes)" if rep["built"]["dirty"] else "")
                + f" from {rep['built']['grid']} and {rep['built']['anchors']}."] if "built" in rep else []), "",
             "| method | IQM | mean | optimality gap | seeds per task |", "|---|---|---|---|---|"]
    for m, name in zip(rep["methods"], names(rep["methods"])):
        e = rep["methods"][m]
        lines.append(f"| {name} | {_interval(e['IQM'])} | {_interval(e['mean'])} | {_interval(e['optimality gap'])} "
                     f"| {', '.join(map(str, e['seeds_per_task']))} |")
    # A report whose pairs name their reference (the benchmark's: its student's Gaussian noise, its best fixed
    # noise) says which reference each Y is.
    against = any("reference" in p for p in rep["improvement"])
    # Reports written before the per-task terms existed have none: no column then.
    per_task = all("per_task" in p for p in rep["improvement"])
    lines += ["", "## Probability of improvement", "",
              "P(X > Y): the chance that a seed of X ends above a seed of Y on a task drawn from the grid's tasks; "
              "0.5 = neither tends to end higher. 95% stratified bootstrap interval in brackets"
              + ("; per task: the terms it averages, in the order of the tasks above (a difference of a few "
                 "points where both end at a task's ceiling counts there as much as a large one)" if per_task else "")
              + ".", "",
              "| X | Y |" + (" Y is |" if against else "") + " P(X > Y) |" + (" per task |" if per_task else ""),
              "|---|---|" + ("---|" if against else "") + "---|" + ("---|" if per_task else "")]
    if not rep["improvement"]:
        lines.append("| (no pair to compare) | | " + ("| " if against else "") + "|" + (" |" if per_task else ""))
    for p in rep["improvement"]:
        lines.append(f"| {labels.get(p['x'], p['x'])} | {labels.get(p['y'], p['y'])} |"
                     + (f" {p.get('reference', '')} |" if against else "") + f" {_interval(p)} |"
                     + (f" {', '.join(stats.fmt(v, 2) for v in p['per_task'])} |" if per_task else ""))
    return "\n".join(lines) + "\n"


def plot_profiles(methods: list[str], scores: dict, path: str, title: str, labels: dict | None = None) -> None:
    """Performance profiles of ``grid_scores``'s methods and scores: the fraction of seeds (pooled over the
    tasks) above each normalised score."""
    labels = {**METHOD_NAMES, **(labels or {})}
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    taus = profile_taus({m: scores[m] for m in methods})
    for i, m in enumerate(methods):
        point, lo, hi = stats.performance_profile(scores[m], taus)
        # past the colour cycle's 10 colours, the next 10 lines are dashed, then dotted
        line, = ax.plot(taus, point, label=labels.get(m, m), linestyle=("-", "--", ":")[i // 10 % 3])
        ax.fill_between(taus, lo, hi, alpha=0.15, color=line.get_color())
    ax.set_xlabel("normalised final return τ (0 = random policy, 1 = reference)")
    ax.set_ylabel("fraction of seeds with score > τ")
    ax.set_title(f"{title}: performance profiles (95% stratified bootstrap bands)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120, metadata={"Software": None})
    plt.close(fig)


def repo_path(path: str) -> str:
    """``path`` relative to the repository's root, as the reports name their inputs."""
    return os.path.relpath(os.path.abspath(path), os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def write(rep: dict, scored: tuple, out: str, title: str, built: dict, labels: dict | None = None) -> list[str]:
    """aggregate.json, aggregate.md and performance_profiles.png of ``report``'s ``rep`` (from ``scored``, the
    result of ``grid_scores``) in ``out``, with ``built`` (date, commit, dirty, grid, anchors) as provenance;
    ``labels``: as ``markdown``'s."""
    from metapg_jax.host.runfiles import write_json_atomic

    os.makedirs(out, exist_ok=True)
    rep["built"] = built
    paths = [os.path.join(out, n) for n in ("aggregate.md", "aggregate.json", "performance_profiles.png")]
    write_json_atomic(paths[1], rep)
    with open(paths[0], "w") as f:
        f.write(markdown(rep, title, labels))
    plot_profiles(scored[1], scored[2], paths[2], title, labels)
    return paths


def main(argv: list[str] | None = None) -> int:
    from experiments.normalisation import DEFAULT_OUT, load
    from metapg_jax.host.provenance import record as provenance

    p = argparse.ArgumentParser(prog="python -m experiments.aggregate", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("grid", help="a grid's JSON twin, e.g. results/table2.json")
    p.add_argument("--anchors", default=DEFAULT_OUT, help="normalisation anchors (default results/normalisation.json)")
    p.add_argument("--out", default=None, help="output folder (default: the grid file's folder)")
    args = p.parse_args(argv)
    for path, what in ((args.grid, "grid"), (args.anchors, "anchors")):
        if not os.path.isfile(path):
            print(f"error: {what} file {path} not found" + (" (python -m experiments.normalisation writes it)"
                                                          if what == "anchors" else ""), file=sys.stderr)
            return 2
    try:
        anchors = load(args.anchors)
    except (OSError, ValueError, KeyError, TypeError) as err:
        print(f"error: {args.anchors} is not an anchors file ({type(err).__name__}: {err})", file=sys.stderr)
        return 2
    try:
        with open(args.grid) as f:
            grid = json.load(f)
        scored = grid_scores(grid, anchors)
        rep = report(grid, anchors, scored)
    except KeyError as err:
        print(f"error: {args.grid}: a grid's JSON twin needs the field {err} (experiments.analysis.tables writes them)",
              file=sys.stderr)
        return 2
    except (OSError, ValueError, TypeError) as err:
        print(f"error: {args.grid}: {err}", file=sys.stderr)
        return 2
    built = provenance()
    out = args.out or os.path.dirname(os.path.abspath(args.grid))
    title = f"{grid.get('preset', '?')} preset" + (f" ({os.path.basename(out)})" if os.path.basename(out) != "results" else "")
    write(rep, scored, out, title, {"date": datetime.date.today().isoformat(), "commit": built["commit"],
                                    "dirty": built["dirty"], "grid": repo_path(args.grid),
                                    "anchors": repo_path(args.anchors)})
    print(f"wrote aggregate.md, aggregate.json and performance_profiles.png to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
