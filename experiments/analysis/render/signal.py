"""The signal check's files and command (``python -m experiments.analysis.signal``, whose module docstring states
the measures and the pass rule): ``signal.md`` and ``signal.json`` beside the variants' grid folders."""

from __future__ import annotations

import argparse
import datetime
import os
import sys

from experiments.analysis import signal
from experiments.analysis.stats import fmt, fmt_p
from experiments.grid.methods import METHOD_NAMES, task_name


def _x(v: float) -> str:
    return "inf" if v == float("inf") else f"{v:.2f}"


def markdown(result: dict) -> str:
    lines = [f"# The meta reward's signal on fixed D0s ({result['student'].upper()})", "",
             f"Pass rule, fixed before the grids ran: {result['pass_rule']}. Rank agreement: Spearman's rho over the "
             f"{len(result['d0s'])} D0s, its 95% interval from {result['reps']:,} bootstrap resamples of the seeds "
             "within each cell; separation: best-minus-worst gap of the D0s' mean meta rewards (each seed's mean over "
             "its cycles) over the seeds' pooled std; effect: Kruskal-Wallis p of the D0s' final returns.", "",
             "| variant | task | rho [95% CI] | separation | effect p | outcome |", "|---|---|---|---|---|---|"]
    for v in result["variants"]:
        for r in v["tasks"]:
            if "rho" in r:
                lines.append(f"| {v['variant']} | {task_name(r['task'])} | {r['rho']:.2f} [{r['rho_lo']:.2f}, "
                             f"{r['rho_hi']:.2f}] | {_x(r['separation'])} | {fmt_p(r['effect_p'])} | {r['outcome']} |")
            else:
                lines.append(f"| {v['variant']} | {task_name(r['task'])} | – | – | – | {r['outcome']} |")
    lines += ["", "| variant | tasks passed | outcome |", "|---|---|---|"]
    lines += [f"| {v['variant']} | {v['passed']} of {len(v['tasks'])} | {v['outcome']} |" for v in result["variants"]]
    lines += ["", "## Per D0", "", "Meta reward: mean over seeds of each seed's mean over its cycles ± the std over "
              "seeds of those means. Final return: mean ± std over seeds.", "",
              "| variant | task | D0 | seeds | meta reward | final return |", "|---|---|---|---|---|---|"]
    for v in result["variants"]:
        for r in v["tasks"]:
            for d0, c in r["cells"].items():
                name = METHOD_NAMES.get(d0, d0)
                if c["state"] != "finished":
                    lines.append(f"| {v['variant']} | {task_name(r['task'])} | {name} | – | {c['state']} | – |")
                else:
                    lines.append(f"| {v['variant']} | {task_name(r['task'])} | {name} | {c['seeds']} | "
                                 f"{fmt(c['reward_mean'])} ± {fmt(c['reward_seed_std'])} | "
                                 f"{fmt(c['return_mean'])} ± {fmt(c['return_std'])} |")
    lines += ["", f"Per-seed values in `signal.json`. Built {result['built']} at commit `{result['commit']}`"
              + (" (uncommitted changes)" if result["dirty"] else "") + ".", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    from metapg_jax.host.provenance import record
    from metapg_jax.host.runfiles import json_numbers, write_json_atomic, write_text_atomic

    p = argparse.ArgumentParser(prog="python -m experiments.analysis.signal", description=signal.__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--results-dir", required=True, help="the folder of the variants' grid folders")
    p.add_argument("--variants", required=True, help="comma-separated: each a grid folder under --results-dir")
    p.add_argument("--tasks", required=True, help="comma-separated tasks of the grids")
    p.add_argument("--reps", type=int, default=signal.REPS, help=f"bootstrap resamples (default {signal.REPS})")
    a = p.parse_args(argv)
    variants = [v for v in a.variants.split(",") if v]
    tasks = [t for t in a.tasks.split(",") if t]
    missing = [v for v in variants if not os.path.isdir(os.path.join(a.results_dir, v))]
    if missing or not variants or not tasks or a.reps < 100:
        why = (f"no grid folder {os.path.join(a.results_dir, missing[0])}" if missing else
               "--reps must be at least 100" if a.reps < 100 else "--variants and --tasks must name at least one")
        print(f"error: {why}", file=sys.stderr)
        return 2
    prov = record()
    result = {**signal.check(a.results_dir, variants, tasks, a.reps),
              "built": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
              "commit": prov.get("commit"), "dirty": prov.get("dirty")}

    write_json_atomic(os.path.join(a.results_dir, "signal.json"), json_numbers(result))
    write_text_atomic(os.path.join(a.results_dir, "signal.md"), markdown(result))
    for v in result["variants"]:
        print(f"{v['variant']}: passed on {v['passed']} of {len(v['tasks'])} tasks: {v['outcome']}")
    print(f"wrote {os.path.join(a.results_dir, 'signal.md')} and signal.json")
    return 0
