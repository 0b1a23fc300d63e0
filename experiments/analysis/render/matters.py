"""A benchmark's ``exploration_matters.md`` and ``.json``: per task, how far its best and worst entries lie apart
against the seeds' spread (``experiments.analysis.benchmark.exploration_matters``, whose definition the page
states)."""

from __future__ import annotations

import json
import math
import os

from experiments.analysis.benchmark import MATTERS_DEFINITION, Entry
from experiments.grid.methods import task_name
from metapg_jax.host.runfiles import json_number


def _entry(key: str) -> str:
    """An entry's key (``<student>/<method>``) as the benchmark's tables name it (``Entry.label``)."""
    return Entry(*key.split("/", 1)).label


def write_matters(rows: list[dict], out_dir: str, footer: str) -> list[str]:
    """``exploration_matters.md`` and ``.json`` of ``rows``; returns the paths."""
    paths = [os.path.join(out_dir, "exploration_matters.md"), os.path.join(out_dir, "exploration_matters.json")]
    md = ["# Where exploration matters (exploration benchmark)", "", f"- {MATTERS_DEFINITION}.",
          "- A task is listed once two of its cells finished at one budget.", "",
          "| task | budget | cells | best entry | worst entry | spread | pooled seed std | spread / seed std | "
          "spread / range |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        figure = "inf" if math.isinf(r["figure"]) else f"{r['figure']:.2f}"
        frac = "–" if r["spread_fraction"] is None else f"{r['spread_fraction']:.3f}"
        md.append(f"| {task_name(r['task'])} | {r['budget']:,} | {r['cells']} | {_entry(r['best'])} | "
                  f"{_entry(r['worst'])} | {r['spread']:.4g} | {r['pooled_std']:.4g} | {figure} | {frac} |")
    if not rows:
        md.append("| (no task has two finished cells) | | | | | | | | |")
    md.append(footer)
    with open(paths[0], "w") as f:
        f.write("\n".join(md))
    with open(paths[1], "w") as f:  # an infinite figure (no seed spread, entries apart) is written as null
        json.dump({"definition": MATTERS_DEFINITION,
                   "tasks": [{**r, "figure": json_number(r["figure"])} for r in rows]},
                  f, indent=2)
    return paths
