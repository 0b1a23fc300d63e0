"""The two-engine comparison's files and command (``python -m experiments.analysis.engines``, whose module docstring
states what is compared and how): ``engines.md`` and ``engines.json``."""

from __future__ import annotations

import argparse
import datetime
import json
import os
import sys

from experiments.analysis import engines
from experiments.analysis.stats import EQUIVALENCE_MARGIN, fmt, fmt_p
from experiments.grid.methods import METHOD_NAMES, task_name


def _name(method: str) -> str:
    return METHOD_NAMES.get(method, method)


def markdown(result: dict) -> str:
    first, second = result["labels"]
    lines = [f"# Table 2 on two engines: {first} and {second}", "",
             f"{first}: `{result['first']}`; {second}: `{result['second']}` (each grid's seeds, base seed and "
             "budget are in its own table). The methods' order on each task by mean final return; Kendall's tau "
             "between the two orders; a pair of methods swapped between the engines with each grid's own Welch p "
             "of the pair (raw: a swap neither grid separates is no disagreement about which is better).", "",
             f"| task | order on {first} | order on {second} | tau | same order |", "|---|---|---|---|---|"]
    for t in result["tasks"]:
        lines.append(f"| {task_name(t['task'])} | {' > '.join(map(_name, t['first_order']))} | "
                     f"{' > '.join(map(_name, t['second_order']))} | {t['kendall_tau']:.2f} | "
                     f"{'yes' if t['same_order'] else 'no'} |")
    swaps = [(t["task"], s) for t in result["tasks"] for s in t["swapped"]]
    if swaps:
        lines += ["", f"| task | swapped pair (above on {first}, below it on {second}) | p on {first} | "
                      f"p on {second} |", "|---|---|---|---|"]
        lines += [f"| {task_name(task)} | {_name(s['pair'][0])} / {_name(s['pair'][1])} | {fmt_p(s['first_p'])} | "
                  f"{fmt_p(s['second_p'])} |" for task, s in swaps]
    lines += ["", f"## Each cell on both engines ({second} − {first})", "",
              f"Verdicts: two-sided Welch t-test of a method's seeds' final returns on {second} against those on "
              f"{first}, Holm-corrected over the {len(result['cells'])} cells; 'better' / 'worse' where the "
              "corrected p < 0.05; 'equivalent' where the two one-sided Welch tests of a difference within "
              f"±{EQUIVALENCE_MARGIN:.0%} of the task's normalised range (" +
              (f"`{result['anchors']}`" if result["anchors"] else "no anchors given: nothing is judged equivalent") +
              "), Holm-corrected over the same cells, give p < 0.05; otherwise 'inconclusive'.",
              "", f"| task | method | {first} (seeds) | {second} (seeds) | difference [95% CI] | Holm p | verdict |",
              "|---|---|---|---|---|---|---|"]
    for c in result["cells"]:
        ci = c["ci95"]
        lines.append(f"| {task_name(c['task'])} | {_name(c['method'])} | {fmt(c['first_mean'])} ({c['first_n']}) | "
                     f"{fmt(c['second_mean'])} ({c['second_n']}) | {fmt(c['difference'])} "
                     f"[{fmt(ci[0]) if ci else '–'}, {fmt(ci[1]) if ci else '–'}] | {fmt_p(c['p_holm'])} | "
                     f"{c['verdict']} |")
    counts = {v: sum(c["verdict"] == v for c in result["cells"]) for v in ("better", "worse", "equivalent",
                                                                          "inconclusive")}
    lines += ["", f"{len(result['cells'])} cells: " + ", ".join(f"{n} {v}" for v, n in counts.items()) +
              f" ({second} against {first}).", "",
              f"Built {result['built']} at commit `{result['commit']}`" +
              (" (uncommitted changes)" if result["dirty"] else "") + ".", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    from experiments import normalisation
    from metapg_jax.host.provenance import record
    from metapg_jax.host.runfiles import json_numbers, write_json_atomic, write_text_atomic

    p = argparse.ArgumentParser(prog="python -m experiments.analysis.engines", description=engines.__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--first", required=True, help="the first grid's table2.json (e.g. the MJX grid's)")
    p.add_argument("--second", required=True, help="the second grid's table2.json (e.g. the C engine's)")
    p.add_argument("--labels", default="first,second", help="the two grids' names, comma-separated (e.g. MJX,C)")
    p.add_argument("--anchors", default=None, help="normalisation anchors of the equivalence margins (default: none, "
                                                   "so no cell is judged equivalent)")
    p.add_argument("--out", required=True, help="folder for engines.md and engines.json")
    a = p.parse_args(argv)
    labels = [x.strip() for x in a.labels.split(",")]
    bad = next((f for f in (a.first, a.second, a.anchors) if f and not os.path.isfile(f)), None)
    if bad or len(labels) != 2 or not all(labels):
        print("error: " + (f"no such file {bad}" if bad else "--labels needs two names, e.g. MJX,C"), file=sys.stderr)
        return 2
    with open(a.first) as f1, open(a.second) as f2:
        first, second = json.load(f1), json.load(f2)
    anchors = normalisation.load(a.anchors) if a.anchors else None
    prov = record()
    result = {**engines.compare(first, second, anchors), "labels": labels, "first": a.first, "second": a.second,
              "anchors": a.anchors, "built": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
              "commit": prov.get("commit"), "dirty": prov.get("dirty")}
    if not result["cells"]:
        print(f"error: {a.first} and {a.second} have no finished cell of the same task and method", file=sys.stderr)
        return 2
    os.makedirs(a.out, exist_ok=True)

    write_json_atomic(os.path.join(a.out, "engines.json"), json_numbers(result))
    write_text_atomic(os.path.join(a.out, "engines.md"), markdown(result))
    same = sum(t["same_order"] for t in result["tasks"])
    print(f"{same} of {len(result['tasks'])} tasks in the same order on {labels[0]} and {labels[1]}; wrote "
          f"{os.path.join(a.out, 'engines.md')} and engines.json")
    return 0
