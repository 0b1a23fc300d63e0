"""Diagnostics of the learned-exploration variants and controls (results/learned/README.md): what each hypothesis
predicts, measured from the archived per-cycle metrics (``cells.ARCHIVE_CYCLES``) of a benchmark's finished cells.

    python -m experiments.build.learned --results-dir results/learned/screen --tasks hopper,halfcheetah

Per (student, task, method) of ``grid.LEARNED_METHODS`` with a finished archived cell, over each seed's last
``LAST`` cycles (all of them if it has fewer), pooled over seeds unless said otherwise:

* the meta reward's noise (H3): the root mean square over cycles of its spread over the eval envs, paired
  (``meta_reward_sd_paired``, the per-env differences of R_hat(pi') and R_hat(pi) from the same resets) and
  unpaired (``meta_reward_sd_unpaired``, what the difference of independent rollouts would spread), and their
  ratio (of RMS spreads, i.e. the square root of the ratio of mean variances: each cycle's variances are
  unbiased, so a pairing that changes nothing gives about 1, where a ratio of median spreads over two envs
  would lean toward pairing); the meta reward's mean and standard deviation over cycles, and |mean| / std;
* D0's distance from the student (H1): the RMS teacher-student action distance, mean ± std over seeds of each
  seed's mean;
* the bandit's choice (H2, ``--teacher=bandit`` with two or more scales): per seed the arm chosen most often and
  its share of the cycles; the seeds whose favourite has more than half; the favourite scales' counts.

Writes ``<results-dir>/diagnostics.md`` and ``diagnostics.json``. A cell that is not finished, or whose cycles are
not archived, is listed as such: nothing is estimated.
"""

from __future__ import annotations

import argparse
import gzip
import json
import math
import os
import sys
from collections import Counter

import numpy as np

from experiments.build import stats
from experiments.build.cells import ARCHIVE_CYCLES, build_info
from experiments.build.grid import LEARNED, METHOD_NAMES, STUDENT_NAMES, task_folder, task_name

LAST = 100  # cycles per seed at the end of training that the diagnostics read


def read_cycles(path: str) -> dict[int, list[dict]]:
    """{seed: its cycles' rows in cycle order} from a cell's ``cycles.jsonl.gz``."""
    seeds: dict[int, list[dict]] = {}
    with gzip.open(path, "rt") as f:
        for line in f:
            row = json.loads(line)
            seeds.setdefault(int(row["seed"]), []).append(row)
    return {s: sorted(rows, key=lambda r: r["cycle"]) for s, rows in sorted(seeds.items())}


def _finite(values) -> np.ndarray:
    x = np.asarray([v for v in values if v is not None], np.float64)
    return x[np.isfinite(x)]


def _rms(values) -> float | None:
    x = _finite(values)
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else None


def cell_diagnostics(cell_dir: str, last: int = LAST) -> dict:
    """The diagnostics of one archived cell (module docstring); ``{"state": ...}`` only when it cannot have any."""
    if not os.path.exists(os.path.join(cell_dir, "summary.json")):
        return {"state": "not run"}
    cycles_path = os.path.join(cell_dir, ARCHIVE_CYCLES)
    if not os.path.exists(cycles_path):
        return {"state": "no per-cycle metrics archived"}
    with open(os.path.join(cell_dir, "config.json")) as f:
        config = json.load(f)["config"]
    tail = {s: rows[-last:] for s, rows in read_cycles(cycles_path).items()}
    rows = [r for rs in tail.values() for r in rs]
    reward = _finite(r["meta_reward"] for r in rows)
    paired = _rms(r.get("meta_reward_sd_paired") for r in rows)
    unpaired = _rms(r.get("meta_reward_sd_unpaired") for r in rows)
    distance = [float(np.mean(_finite(r["teacher_student_distance"] for r in rs))) for rs in tail.values()]
    out = {"state": "finished", "seeds": len(tail), "cycles_per_seed": min(len(rs) for rs in tail.values()),
           "sd_paired_rms": paired, "sd_unpaired_rms": unpaired,
           "sd_ratio": paired / unpaired if paired is not None and unpaired else None,
           "meta_reward_mean": float(np.mean(reward)) if reward.size else None,
           "meta_reward_std": float(np.std(reward, ddof=1)) if reward.size > 1 else None,
           "distance_mean": float(np.mean(distance)), "distance_std": float(np.std(distance, ddof=1))
           if len(distance) > 1 else None}
    m, s = out["meta_reward_mean"], out["meta_reward_std"]
    out["meta_reward_snr"] = abs(m) / s if m is not None and s else None
    meta = config.get("meta", {})
    scales = config.get("bandit", {}).get("scales", [])
    if meta.get("teacher") == "bandit" and len(scales) > 1:
        logs = np.log(np.maximum(np.asarray(scales, np.float64), 1e-6))
        favourites = []
        for rs in tail.values():
            arms = [int(np.argmin(np.abs(logs - r["teacher_log_std"]))) for r in rs
                    if r.get("teacher_log_std") is not None]
            arm, n = Counter(arms).most_common(1)[0]
            favourites.append({"scale": float(scales[arm]), "share": n / len(rs)})
        out["bandit"] = {"scales": [float(x) for x in scales], "favourites": favourites,
                         "seeds_over_half": sum(f["share"] > 0.5 for f in favourites),
                         "favourite_counts": {f"{k:g}": v for k, v in
                                              sorted(Counter(f["scale"] for f in favourites).items())}}
    return out


def build(results_dir: str, tasks: list[str], students: list[str], last: int = LAST) -> dict:
    """{"cells": [{student, task, method, **cell_diagnostics}], "last": last, "built": provenance}."""
    cells = []
    for student in students:
        for task in tasks:
            for method in LEARNED[student]:
                d = os.path.join(results_dir, student, "cells", task_folder(task), method)
                cells.append({"student": student, "task": task, "method": method, **cell_diagnostics(d, last)})
    return {"last": last, "cells": cells, "built": build_info(results_dir)}


def _f(x, digits=2) -> str:
    return "–" if x is None or (isinstance(x, float) and not math.isfinite(x)) else stats.fmt(x, digits)


def markdown(report: dict) -> str:
    last = report["last"]
    lines = ["# Learned exploration: diagnostics of the variants and controls", "",
             f"From each finished cell's archived per-cycle metrics (`cycles.jsonl.gz`), over each seed's last {last} "
             "cycles, pooled over seeds. Meta reward spread: the root mean square over cycles of the spread (sample "
             "std) over the cycle's eval envs of the per-env differences R_hat(pi') - R_hat(pi) from the same resets "
             "(paired), and of what the difference of independent rollouts would spread, sqrt(sd(R_hat(pi'))^2 + "
             "sd(R_hat(pi))^2) (unpaired); ratio: paired over unpaired (about 1 where pairing changes nothing). "
             "Meta reward mean ± std: over the cycles; SNR = |mean| / std. Distance: "
             "the RMS teacher-student action distance on D0 (actions in [-1, 1]), mean ± std over seeds of each "
             "seed's mean. Bandit: per seed the scale chosen most often and its share of the cycles.", "",
             "| student | task | method | seeds | spread paired | spread unpaired | ratio | meta reward mean ± std | "
             "SNR | distance | bandit: seeds whose favourite has > 1/2 | bandit: favourite scales (seeds) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for c in report["cells"]:
        head = f"| {STUDENT_NAMES.get(c['student'], c['student'])} | {task_name(c['task'])} | " \
               f"{METHOD_NAMES.get(c['method'], c['method'])} |"
        if c["state"] != "finished":
            lines.append(head + f" {c['state']} |" + " |" * 8)
            continue
        b = c.get("bandit")
        lines.append(head + f" {c['seeds']} | {_f(c['sd_paired_rms'], 3)} | {_f(c['sd_unpaired_rms'], 3)} | "
                     f"{_f(c['sd_ratio'])} | {_f(c['meta_reward_mean'], 3)} ± {_f(c['meta_reward_std'], 3)} | "
                     f"{_f(c['meta_reward_snr'])} | {_f(c['distance_mean'])} ± {_f(c['distance_std'])} | "
                     + (f"{b['seeds_over_half']} of {c['seeds']} | "
                        + ", ".join(f"{k} ({v})" for k, v in b["favourite_counts"].items()) + " |" if b else "– | – |"))
    b = report["built"]
    lines += ["", "---", "", f"Built {b['built']} from `{b['runs_dir']}` at commit `{b['commit']}`"
              + (" (uncommitted changes)" if b.get("dirty") else "") + f" on {b['machine']['platform']}."]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.build.learned", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--results-dir", default="results/learned/screen", help="a benchmark's results folder")
    p.add_argument("--tasks", default="hopper,halfcheetah", help="comma-separated tasks (default hopper,halfcheetah)")
    p.add_argument("--students", default="td3", help=f"comma-separated students of {', '.join(LEARNED)} (default td3)")
    p.add_argument("--last", type=int, default=LAST, help=f"cycles per seed at the end of training (default {LAST})")
    a = p.parse_args(argv)
    students = [s for s in a.students.split(",") if s]
    tasks = [t for t in a.tasks.split(",") if t]
    bad = [s for s in students if s not in LEARNED]
    if bad or not students or not tasks or a.last <= 0:
        print(f"error: students must be among {', '.join(LEARNED)}, tasks non-empty and --last positive",
              file=sys.stderr)
        return 2
    if not os.path.isdir(a.results_dir):
        print(f"error: no folder {a.results_dir!r}", file=sys.stderr)
        return 2
    report = build(a.results_dir, tasks, students, a.last)
    with open(os.path.join(a.results_dir, "diagnostics.json"), "w") as f:
        json.dump(report, f, indent=1)
        f.write("\n")
    with open(os.path.join(a.results_dir, "diagnostics.md"), "w") as f:
        f.write(markdown(report))
    done = sum(c["state"] == "finished" for c in report["cells"])
    print(f"diagnostics of {done} of {len(report['cells'])} cells in {a.results_dir}/diagnostics.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
