"""The seed plan's files and command (``python -m experiments.analysis.power``, whose module docstring states the
rule): ``seeds.md`` and ``seeds.json`` in a pilot benchmark's results folder, from its per-task tables
(``tasks/<task>.json``: each finished cell's final return per seed) and a normalisation anchors file."""

from __future__ import annotations

import argparse
import datetime
import json
import os
import sys

from experiments.analysis import power
from experiments.analysis.benchmark import read_task_tables
from experiments.grid.methods import task_name


def pilot_finals(results_dir: str) -> dict[str, dict[str, list[float]]]:
    """{task: {"<student>/<method>": final returns per seed}} of every finished cell in ``results_dir/tasks``."""
    out = {}
    for task, table in read_task_tables(results_dir).items():
        cells = {f"{r['student']}/{r['method']}": [float(x) for x in r["per_seed"]]
                 for r in table["rows"] if r.get("status") == "done" and r.get("per_seed")}
        if len(cells) >= 2:  # the figure and the pooled spread need two entries
            out[task] = cells
    return out


def _n(x: float) -> str:
    return "inf" if x == float("inf") else f"{x:.2f}"


def markdown(plan: dict) -> str:
    rule = plan["rule"]
    lines = [f"# Seeds by power: {plan['pilot']}", "",
             f"The rule ({rule['definition']}): per task, the fewest seeds (at least {rule['minimum']}) whose Welch "
             f"test at level {rule['alpha']:g} / {rule['comparisons']} (the first Holm step of a family of "
             f"{rule['comparisons']} comparisons) detects a difference of {rule['fraction']:g} of the task's range "
             f"(reference - random policy, `{rule['anchors']}`) with power {rule['power']:g}, given the seeds' "
             f"standard deviation pooled over the pilot's entries; at most {rule['maximum']} (the cost cap). Where "
             f"the rule asks for more than the cap, the detectable column says what the capped count detects.", "",
             "| task | pilot entries x seeds | pooled seed std (of range) | needed | planned seeds | detectable "
             "(of range) | best - worst entry (of range) | spread / seed std |",
             "|---|---|---|---|---|---|---|---|"]
    for r in plan["tasks"]:
        seeds = sorted(set(r["pilot_seeds"].values()))
        lines.append(f"| {task_name(r['task'])} | {r['entries']} x {'/'.join(map(str, seeds))} | "
                     f"{r['pooled_std']:.4g} ({r['std_fraction']:.3f}) | "
                     f"{'more than ' + str(rule['maximum']) if r['capped'] else r['needed']} | {r['seeds']} | "
                     f"{r['detectable_fraction']:.3f} | {r['matters_spread']:.4g} ({r['spread_fraction']:.3f}; "
                     f"{r['matters_best']} over {r['matters_worst']}) | {_n(r['matters_figure'])} |")
    cost = plan.get("cost")
    if cost:
        lines += ["", f"Projected CPU of the judged grid at these seeds ({cost['entries']} entries per task; the "
                      f"pilot's own CPU per seed of a cell on this machine, `{cost['source']}`, times the planned "
                      "seeds and entries; a cell's CPU grows at most about linearly with its seeds, its compile is "
                      "paid once: a projection that leans high, not a measurement):", "",
                  "| task | CPU s per seed (pilot) | projected CPU h |", "|---|---|---|"]
        lines += [f"| {task_name(r['task'])} | "
                  f"{'–' if r['cpu_per_seed'] is None else format(r['cpu_per_seed'], '.1f')} | "
                  f"{'–' if r['projected_cpu_hours'] is None else format(r['projected_cpu_hours'], '.2f')} |"
                  for r in plan["tasks"]]
        lines += ["", f"Total: {cost['total_hours']:.1f} CPU h" + (
            f" against a cap of {cost['cap_hours']:g} CPU h" + (": **over the cap**" if cost["total_hours"] >
                                                                cost["cap_hours"] else "")
            if cost.get("cap_hours") else "") + "."]
    lines += ["", "As benchmark options: `" + " ".join(f"--task-seeds {r['task']}={r['seeds']}" for r in plan["tasks"])
              + "`", "", f"Built {plan['built']} at commit `{plan['commit']}`"
              + (" (uncommitted changes)" if plan["dirty"] else "") + f" from `{plan['pilot']}`.", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    from experiments import normalisation
    from metapg_jax.host.provenance import record
    from metapg_jax.host.runfiles import json_number, write_json_atomic, write_text_atomic

    p = argparse.ArgumentParser(prog="python -m experiments.analysis.power", description=power.__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--results-dir", required=True, help="a pilot benchmark's results folder (its tasks/*.json)")
    p.add_argument("--anchors", required=True, help="the normalisation anchors of its tasks")
    p.add_argument("--comparisons", type=int, required=True,
                   help="the size of the largest verdict family the judged grid will have (e.g. TD3's: 6 entries "
                        "against its baseline on 7 tasks, 42)")
    p.add_argument("--fraction", type=float, default=0.1, help="the difference that matters, as a fraction of the "
                                                                "task's range (default 0.1)")
    p.add_argument("--minimum", type=int, default=10, help="the fewest seeds a cell gets (default 10)")
    p.add_argument("--maximum", type=int, default=40, help="the most seeds a cell gets: the cost cap (default 40)")
    p.add_argument("--entries", type=int, default=None,
                   help="the judged grid's entries per task: project its CPU from the pilot's cost.json")
    p.add_argument("--cap-hours", type=float, default=None, help="the grid's CPU cap in hours, to hold the projection "
                                                                  "against (with --entries)")
    p.add_argument("--out", default=None, help="the folder of seeds.md and seeds.json (default --results-dir)")
    a = p.parse_args(argv)
    try:
        if not os.path.isdir(os.path.join(a.results_dir, "tasks")):
            raise ValueError(f"{a.results_dir}: no tasks/ folder (build the pilot's artefacts first)")
        if not os.path.isfile(a.anchors):
            raise ValueError(f"--anchors {a.anchors}: no such file")
        finals = pilot_finals(a.results_dir)
        if not finals:
            raise ValueError(f"{a.results_dir}: no task has two finished cells")
        rows = power.seed_plan(finals, normalisation.load(a.anchors), a.fraction, a.comparisons, a.minimum,
                               a.maximum)
        cost = None
        if a.entries is not None:
            source = os.path.join(a.results_dir, "cost.json")
            if not os.path.isfile(source):
                raise ValueError(f"--entries: {source} not found (build the pilot's artefacts first)")
            with open(source) as f:
                total = power.project_cost(rows, power.cpu_per_seed(json.load(f)["cells"]), a.entries)
            cost = {"entries": a.entries, "source": source, "total_hours": total, "cap_hours": a.cap_hours}
        elif a.cap_hours is not None:
            raise ValueError("--cap-hours needs --entries")
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    out = a.out or a.results_dir
    os.makedirs(out, exist_ok=True)
    prov = record()
    plan = {"pilot": a.results_dir, "built": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
            "commit": prov.get("commit"), "dirty": prov.get("dirty"),
            "rule": {"definition": "experiments.analysis.power.seed_plan", "fraction": a.fraction,
                     "comparisons": a.comparisons, "alpha": power.ALPHA, "power": power.POWER, "minimum": a.minimum,
                     "maximum": a.maximum, "anchors": a.anchors},
            "tasks": rows, **({"cost": cost} if cost else {})}
    write_json_atomic(os.path.join(out, "seeds.json"),  # an infinite figure (no seed spread) is written as null
                      {**plan, "tasks": [{k: json_number(v) if isinstance(v, float) else v for k, v in r.items()}
                                         for r in rows]})
    write_text_atomic(os.path.join(out, "seeds.md"), markdown(plan))
    for r in rows:
        print(f"{r['task']}: seed std {r['std_fraction']:.3f} of the range, "
              f"{'more than ' + str(a.maximum) if r['capped'] else r['needed']} seeds needed, {r['seeds']} planned "
              f"(detects {r['detectable_fraction']:.3f} of the range); best - worst entry {_n(r['matters_figure'])} "
              f"seed std")
    if cost:
        print(f"projected CPU at these seeds, {a.entries} entries per task: {cost['total_hours']:.1f} h"
              + (f" (cap {a.cap_hours:g} h)" if a.cap_hours else ""))
    print(f"wrote {os.path.join(out, 'seeds.md')} and seeds.json")
    return 0
