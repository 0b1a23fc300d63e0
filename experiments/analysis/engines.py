"""Two engines' Table 2 side by side: the same methods on the same tasks, one grid run on MJX and one on MuJoCo's C
engine (or any two built Table 2 grids), read from their ``table2.json`` alone.

Per cell (task, method) with a finished run on both: each grid's mean over its seeds and the difference second −
first with its 95% Welch interval and a corrected verdict. The cells form one family (``stats.VerdictFamily``:
Welch, Holm over every cell of the comparison; "equivalent" only where the two one-sided tests of the anchors'
margin, 5% of the task's normalised range, reject after the same correction): does the engine change a method's
return?

Per task, the question the paper's table answers: do the methods come out in the same order? The order is by mean
on each engine; Kendall's tau between the two orders; and each pair of methods whose order differs, with each
grid's own Welch p of the pair's difference (raw, descriptive: a swap of two methods that neither grid separates is
no disagreement between the engines about which is better).

    python -m experiments.analysis.engines --first results/mjx/table2.json --second results/table2.json \\
        --labels MJX,C --anchors results/normalisation.json --out results
"""

from __future__ import annotations

import itertools
from typing import Sequence

import numpy as np

from experiments.analysis.stats import VerdictFamily, welch_test


def _finished(row: dict) -> dict[str, list[float]]:
    """{method: per-seed finals} of a table2.json row's finished cells."""
    return {m: [float(x) for x in c["per_seed"]] for m, c in row["methods"].items()
            if c.get("status") == "done" and c.get("per_seed")}


def _order(per_method: dict[str, list[float]], methods: Sequence[str]) -> list[str]:
    """``methods`` best first by mean (ties keep the table's order)."""
    return sorted(methods, key=lambda m: -float(np.mean(per_method[m])))


def kendall_tau(first: Sequence[str], second: Sequence[str]) -> float:
    """Kendall's tau between two orders of the same items (1: the same order, -1: reversed; no ties)."""
    if sorted(first) != sorted(second):
        raise ValueError(f"the two orders hold different items: {sorted(first)} and {sorted(second)}")
    pos = {m: i for i, m in enumerate(second)}
    pairs = list(itertools.combinations(first, 2))
    if not pairs:
        return 1.0
    return sum(1 if pos[a] < pos[b] else -1 for a, b in pairs) / len(pairs)


def compare(first: dict, second: dict, anchors: dict | None = None) -> dict:
    """The comparison of two ``table2.json`` payloads (``first``, ``second``): ``{"cells": [...], "tasks": [...]}``,
    the tasks and methods in ``first``'s order, only those finished in both."""
    rows_b = {r["task"]: _finished(r) for r in second["rows"]}
    family, cells, tasks = VerdictFamily(anchors), [], []
    for row in first["rows"]:
        a, b = _finished(row), rows_b.get(row["task"], {})
        methods = [m for m in a if m in b]
        if not methods:
            continue
        task = row["task"]
        for m in methods:
            family.add((task, m), b[m], a[m], task)
            cells.append({"task": task, "method": m, "first_mean": float(np.mean(a[m])), "first_n": len(a[m]),
                          "second_mean": float(np.mean(b[m])), "second_n": len(b[m])})
        order_a, order_b = _order(a, methods), _order(b, methods)
        swapped = []
        for m1, m2 in itertools.combinations(order_a, 2):  # m1 above m2 on the first grid
            if order_b.index(m1) > order_b.index(m2):
                swapped.append({"pair": [m1, m2], "first_p": welch_test(a[m1], a[m2])[1],
                                "second_p": welch_test(b[m1], b[m2])[1]})
        tasks.append({"task": task, "first_order": order_a, "second_order": order_b,
                      "kendall_tau": kendall_tau(order_a, order_b), "same_order": order_a == order_b,
                      "swapped": swapped})
    for cell, (_, judged) in zip(cells, family.judge()):
        cell.update(judged)
    return {"cells": cells, "tasks": tasks}


if __name__ == "__main__":  # the command's parsing and files are the rendering side's
    import sys

    from experiments.analysis.render.engines import main

    sys.exit(main())
