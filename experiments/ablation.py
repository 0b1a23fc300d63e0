"""Ablations: a few runs of one task compared with a control run, at a common env-step budget.

    python -m experiments.ablation --out results/ablations/halfcheetah --upto 300000 \\
        --run "paper preset=results/cells/halfcheetah/meta-independent" \\
        --run "normalised meta reward=runs/ablation/halfcheetah/normreward" --archive

The first ``--run`` is the control. Every run is cut at ``--upto`` env steps (a longer control, e.g.
the 600k paper cell, is read up to that step: same seeds, same code, so its first ``--upto`` steps
are the run a ``--upto`` budget would have made; the replay buffer never wraps before then), and
compared with the control on the same definitions as ``results/table2.md``:

* final return of a seed = mean of its last 10% (at least 1) evaluations up to ``--upto``;
* mean ± std over seeds (ddof=1), 95% Student-t CI, two-sided Welch t-test vs the control;
* for Meta runs: the teacher's log-std over the same last 10% of evaluations (seed-mean), and how
  many seeds sit at its floor (``meta.min_log_std``).

What differs between a run's config and the control's is listed from the stored configs (not from
the names given on the command line). Writes ``<out>/README.md`` (table), ``per_seed.csv`` and
``curves.png``; with ``--archive`` it first copies each run's result files (the set that
``results/cells`` keeps) to ``<out>/cells/<name>/`` and reads them from there, so the report can
be rebuilt from a fresh clone: ``python -m experiments.ablation --out DIR --rebuild``.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import re
import sys
from typing import Sequence

import numpy as np

from experiments.analysis import cells, stats
from experiments.analysis.render import figures

MANIFEST = "ablation.json"


def slug(name: str) -> str:
    s = re.sub(r"[^a-z0-9]+", "-", name.lower()).strip("-")
    if not s:
        raise ValueError(f"run name {name!r} has no letters or digits")
    return s


def flat(d: dict, prefix: str = "") -> dict:
    """{'group.field': value} of a nested config dict."""
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flat(v, key + "."))
        else:
            out[key] = v
    return out


def config_diff(config: dict, control: dict, ignore: Sequence[str] = ("run.total_steps",)) -> dict:
    """{'group.field': (value, control value)} where the two configs differ. Both go through
    ``from_dict``/``to_dict`` first, so a field added to the config after a run was stored counts at its
    default (what the stored run ran with), not as a difference."""
    from metapg_jax import config as config_lib

    normal = lambda d: config_lib.to_dict(config_lib.from_dict(d))
    a, b = flat(normal(config)), flat(normal(control))
    return {k: (a.get(k), b.get(k)) for k in sorted(set(a) | set(b))
            if k not in ignore and a.get(k) != b.get(k)}


def cut(r: cells.RunResult, upto: int) -> tuple[np.ndarray, np.ndarray]:
    """(steps, values) of the evaluations at env steps <= upto."""
    keep = r.steps <= upto
    return r.steps[keep], r.values[:, keep]


def teacher_log_std(path: str, config: dict, upto: int) -> dict | None:
    """Per-seed teacher log-std over the same window as the final return (the last 10% of the
    evaluations up to ``upto``; each evaluation row holds the mean over its chunk's cycles), its
    seed-mean, and how many seeds are within 0.01 of the floor ``meta.min_log_std``; None for runs
    without a teacher."""
    from metapg_jax.host import metric_rows, runfiles

    if config.get("run", {}).get("method") != "meta":
        return None
    rows = runfiles.read_jsonl(os.path.join(path, "metrics.jsonl"))
    if not rows or "teacher_log_std" not in rows[0]:
        return None
    steps, values = metric_rows.curves(rows, "teacher_log_std")
    per_seed = [float(x) for x in stats.final_returns(np.asarray(values)[:, steps <= upto])]
    floor = float(config["meta"]["min_log_std"])
    return {"mean": float(np.mean(per_seed)), "per_seed": per_seed, "floor": floor,
            "seeds_at_floor": int(sum(x <= floor + 0.01 for x in per_seed))}


def compare(runs: Sequence[tuple[str, cells.RunResult]], upto: int) -> list[dict]:
    """One row per run (the first is the control): finals, stats, config changes, teacher log-std."""
    if upto <= 0:
        raise ValueError(f"--upto must be positive, got {upto}")
    (_, control), rows = runs[0], []
    for name, r in runs:
        if r.task != control.task:
            raise ValueError(f"{name}: task {r.task} differs from the control's ({control.task})")
        if r.env_steps_done < upto:
            raise ValueError(f"{name}: only {r.env_steps_done:,} env steps stored ({r.path}); --upto is {upto:,}")
        if r.num_seeds != control.num_seeds or r.run_args.get("seed") != control.run_args.get("seed"):
            raise ValueError(f"{name}: seeds ({r.num_seeds}, base {r.run_args.get('seed')}) differ from the "
                             f"control's ({control.num_seeds}, base {control.run_args.get('seed')})")
    finals_control = stats.final_returns(cut(control, upto)[1])
    for i, (name, r) in enumerate(runs):
        steps, values = cut(r, upto)
        finals = stats.final_returns(values)
        mean, std = stats.mean_std(finals)
        _, half = stats.t_interval(finals)
        p = math.nan if i == 0 else stats.welch_test(finals, finals_control)[1]
        rows.append({"name": name, "path": r.path, "control": i == 0, "steps": steps, "values": values,
                     "evaluations": int(steps.size),
                     "final_evaluations": stats.num_final_evaluations(int(steps.size)),
                     "finals": finals, "mean": mean, "std": std, "ci_half": half, "p_vs_control": p,
                     "diff": {} if i == 0 else config_diff(r.config, control.config),
                     "teacher": teacher_log_std(r.path, r.config, upto),
                     "budget": r.budget, "commit": r.provenance.get("commit") or r.info.get("commit")})
    family = stats.VerdictFamily(_anchors())
    for r in rows[1:]:
        family.add(r["name"], r["finals"], finals_control, control.task)
    for r, (_, j) in zip(rows[1:], family.judge()):
        r["judged"] = j
    return rows


def _anchors() -> dict | None:
    """The normalisation anchors of the equivalence margins (None without them)."""
    from experiments import normalisation

    return normalisation.load(normalisation.DEFAULT_OUT) if os.path.exists(normalisation.DEFAULT_OUT) else None


def _diff_text(row: dict) -> str:
    if row["control"]:
        return "control"
    if not row["diff"]:
        return "(same config)"
    return "; ".join(f"`{k}={json.dumps(a)}` (control {json.dumps(b)})" for k, (a, b) in row["diff"].items())


def markdown(rows: list[dict], task: str, upto: int, build: dict) -> str:
    control = rows[0]
    lines = [f"# Ablation on {task}: {len(rows) - 1} variant(s) vs {control['name']}", "",
             f"All runs cut at **{upto:,} env steps per seed**, {len(control['finals'])} seeds each (same base seed). "
             f"Final return = mean of the last {control['final_evaluations']} of the "
             f"{control['evaluations']} evaluations up to {upto:,} steps (10%, at least 1), per seed; "
             "mean ± std over seeds (ddof=1); 95% CI: Student t; p: two-sided Welch t-test of the seeds' "
             "final returns vs the control, Holm p: corrected over the variants (one family); "
             + stats.VERDICT_DEFINITION + ". Teacher log-std: per seed over the same evaluations (each the mean "
             "over its chunk's cycles), then the seed-mean (Meta runs only); 'at floor': seeds within 0.01 "
             "of `meta.min_log_std`. "
             "Per-seed numbers: `per_seed.csv`; curves: `curves.png`.", "",
             "| run | changed vs control (from the stored configs) | final (mean ± std) | 95% CI | p vs control "
             "| Holm p | verdict | teacher log-std | seeds at floor |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        t = r["teacher"]
        log_std = "–" if t is None else stats.fmt(t["mean"], 2)
        at_floor = "–" if t is None else f"{t['seeds_at_floor']} of {len(t['per_seed'])}"
        p = "–" if r["control"] else stats.fmt_p(r["p_vs_control"])
        holm, word = ("–", "–") if r["control"] else (stats.fmt_p(r["judged"]["p_holm"]), r["judged"]["verdict"])
        lines.append(f"| {r['name']} | {_diff_text(r)} | {stats.fmt(r['mean'])} ± {stats.fmt(r['std'])} | "
                     f"± {stats.fmt(r['ci_half'])} | {p} | {holm} | {word} | {log_std} | {at_floor} |")
    lines += ["", "---", "",
              f"Built {build['built']} at commit `{build.get('commit') or 'unknown'}` on "
              f"{build['machine']['platform']}. Runs (folder; stored budget; commit of the run):"]
    lines += [f"- {r['name']}: `{r['path']}`; {r['budget']:,} steps; `{r['commit'] or 'unknown'}`" for r in rows]
    return "\n".join(lines) + "\n"


def write_report(rows: list[dict], task: str, upto: int, out: str, build: dict | None = None) -> list[str]:
    """README.md, per_seed.csv and curves.png in ``out``; ``build``: the provenance to print (default: now's)."""
    os.makedirs(out, exist_ok=True)
    build = build or cells.build_info(out)
    md = os.path.join(out, "README.md")
    with open(md, "w") as f:  # rebuildable output: plain writes, like experiments.artefacts
        f.write(markdown(rows, task, upto, build))
    csv_path = os.path.join(out, "per_seed.csv")
    with open(csv_path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["run", "seed", "final_return", "teacher_log_std_final"])
        for r in rows:
            t = r["teacher"]
            for s, v in enumerate(r["finals"]):
                w.writerow([r["name"], s, f"{v:.3f}", "" if t is None else f"{t['per_seed'][s]:.4f}"])
    plt = figures.pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for r in rows:
        mean, std = np.nanmean(r["values"], 0), np.nanstd(r["values"], 0)
        ax.plot(r["steps"], mean, lw=1.8, label=f"{r['name']} ({len(r['finals'])} seeds)")
        ax.fill_between(r["steps"], mean - std, mean + std, alpha=0.15)
    ax.set_xlabel("environment steps")
    ax.set_ylabel("evaluation return")
    ax.set_title(f"{task}: ablation (mean ± std over seeds)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    png = os.path.join(out, "curves.png")
    figures.save_figure(fig, png, build)
    plt.close(fig)
    return [md, csv_path, png]


def archive(path: str, dest: str) -> str:
    """Copies a run's result files (those ``results/cells`` keeps, without the visitation sample) to ``dest``."""
    if not os.path.exists(os.path.join(path, "metrics.jsonl")):
        raise ValueError(f"{path}: no metrics.jsonl (not a run folder)")
    if os.path.abspath(path) == os.path.abspath(dest):
        return dest
    cells.copy_result_files(path, dest)
    return dest


def parse_runs(specs: Sequence[str]) -> list[tuple[str, str]]:
    out = []
    for s in specs:
        name, sep, path = s.partition("=")
        if not sep or not name.strip() or not path.strip():
            raise ValueError(f"--run {s!r}: expected NAME=PATH")
        out.append((name.strip(), path.strip()))
    names = [slug(n) for n, _ in out]
    if len(set(names)) != len(names):
        raise ValueError(f"run names must differ: {', '.join(n for n, _ in out)}")
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.ablation", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, help="report folder (README.md, per_seed.csv, curves.png)")
    p.add_argument("--run", action="append", default=[], metavar="NAME=PATH",
                   help="a run folder; the first is the control (at least two)")
    p.add_argument("--upto", type=int, default=None, help="env steps per seed to compare at")
    p.add_argument("--archive", action="store_true", help="copy the runs' result files to <out>/cells/ first")
    p.add_argument("--rebuild", action="store_true", help=f"re-read the runs and --upto from <out>/{MANIFEST}")
    a = p.parse_args(argv)
    try:
        if a.rebuild:
            with open(os.path.join(a.out, MANIFEST)) as f:
                stored = json.load(f)
            try:
                specs, upto = [(r["name"], r["path"]) for r in stored["runs"]], int(stored["upto"])
            except (KeyError, TypeError) as err:
                raise ValueError(f"{os.path.join(a.out, MANIFEST)} is not an ablation manifest "
                                 f"(missing {err})") from None
        else:
            specs, upto = parse_runs(a.run), a.upto
            if len(specs) < 2:
                raise ValueError("give at least two --run NAME=PATH (the first is the control)")
            if upto is None or upto <= 0:
                raise ValueError("--upto must be a positive number of env steps")
        if os.path.exists(a.out) and not os.path.isdir(a.out):
            raise ValueError(f"--out {a.out} is a file, not a folder")
        if a.archive:
            specs = [(n, archive(path, os.path.join(a.out, "cells", slug(n)))) for n, path in specs]
        runs = []
        for name, path in specs:
            r = cells.load_run(path)
            if r is None:
                raise ValueError(f"{name}: no evaluations stored in {path}")
            runs.append((name, r))
        rows = compare(runs, upto)
    except (ValueError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    from metapg_jax.host import runfiles

    task, build = runs[0][1].task, cells.build_info(a.out)
    files = write_report(rows, task, upto, a.out, build)
    runfiles.write_json_atomic(os.path.join(a.out, MANIFEST),
                                {"task": task, "upto": upto, "runs": [{"name": n, "path": p} for n, p in specs],
                                 "build": build})
    for r in rows:
        t = r["teacher"]
        print(f"{r['name']}: final {r['mean']:.1f} ± {r['std']:.1f}"
              + ("" if r["control"] else f", p vs control {stats.fmt_p(r['p_vs_control'])}")
              + ("" if t is None else f", teacher log-std {t['mean']:.2f} ({t['seeds_at_floor']} seeds at floor)"))
    print("wrote " + ", ".join(files))
    return 0


if __name__ == "__main__":
    sys.exit(main())
