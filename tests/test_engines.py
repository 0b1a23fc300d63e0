"""Table 2 on two engines (experiments/analysis/engines.py): orders, swaps and per-cell verdicts of two fabricated
grids, checked by hand."""

import json

import numpy as np
import pytest
from scipy import stats

from experiments.analysis import engines


def _table(cells: dict) -> dict:
    """A table2.json payload: {task: {method: per-seed finals or None (not run)}}."""
    return {"rows": [{"task": task, "methods": {m: ({"status": "done", "per_seed": v} if v is not None else
                                                    {"status": "not run"}) for m, v in methods.items()}}
                     for task, methods in cells.items()]}


OFFSETS = np.array([-1.0, -0.5, 0.0, 0.5, 1.0, 0.2, -0.2, 0.0])  # mean 0, std 0.65


def _seeds(mean: float, scale: float = 1.0) -> list[float]:
    return list(mean + scale * OFFSETS)


# Pendulum: the same order (a > b > c) on both, b 40 lower on the second engine; Hopper: a above b on the first,
# below it on the second (by 1, within the seeds' spread), c far below both on both; c not run on Hopper's second.
FIRST = _table({"pendulum": {"a": _seeds(-150), "b": _seeds(-200), "c": _seeds(-400)},
                "hopper": {"a": _seeds(1001, 20), "b": _seeds(1000, 20), "c": _seeds(100, 20)}})
SECOND = _table({"pendulum": {"a": _seeds(-150), "b": _seeds(-240), "c": _seeds(-400)},
                 "hopper": {"a": _seeds(1000, 20), "b": _seeds(1001, 20), "c": None}})


def test_orders_swaps_and_cell_verdicts_of_two_fabricated_grids():
    anchors = {"pendulum": (-1400.0, 0.0), "hopper": (0.0, 3800.0)}  # margins 70 and 190
    out = engines.compare(FIRST, SECOND, anchors)

    pend, hop = out["tasks"]
    assert pend["first_order"] == pend["second_order"] == ["a", "b", "c"]
    assert pend["same_order"] and pend["kendall_tau"] == 1.0 and pend["swapped"] == []
    assert hop["first_order"] == ["a", "b"] and hop["second_order"] == ["b", "a"]  # c: not run on the second
    assert not hop["same_order"] and hop["kendall_tau"] == -1.0
    (swap,) = hop["swapped"]
    assert swap["pair"] == ["a", "b"]  # neither grid separates the two (a difference of 1, seed std 13)
    welch = stats.ttest_ind(_seeds(1001, 20), _seeds(1000, 20), equal_var=False).pvalue
    assert swap["first_p"] == pytest.approx(welch) and swap["second_p"] == pytest.approx(welch) and welch > 0.8

    cells = {(c["task"], c["method"]): c for c in out["cells"]}
    assert list(cells) == [("pendulum", "a"), ("pendulum", "b"), ("pendulum", "c"), ("hopper", "a"), ("hopper", "b")]
    b = cells[("pendulum", "b")]
    assert b["difference"] == pytest.approx(-40.0) and b["first_mean"] == pytest.approx(-200.0)
    assert b["first_n"] == b["second_n"] == 8
    # b: 40 lower with a seed std of 0.65: worse after Holm over the 5 cells; a and c: identical seeds, inside
    # Pendulum's margin of 70: equivalent; Hopper's cells differ by 1 within a margin of 190 with a seed std of 13
    assert b["verdict"] == "worse" and b["p_holm"] < 1e-6
    assert cells[("pendulum", "a")]["verdict"] == cells[("pendulum", "c")]["verdict"] == "equivalent"
    assert cells[("hopper", "a")]["verdict"] == cells[("hopper", "b")]["verdict"] == "equivalent"
    assert cells[("hopper", "a")]["difference"] == pytest.approx(-1.0)
    # without anchors nothing is judged equivalent
    assert {c["verdict"] for c in engines.compare(FIRST, SECOND)["cells"]} == {"worse", "inconclusive"}


def test_kendall_tau_by_hand():
    assert engines.kendall_tau(["x", "y", "z"], ["x", "z", "y"]) == pytest.approx(1 / 3)
    assert engines.kendall_tau(["x", "y", "z"], ["z", "y", "x"]) == -1.0
    with pytest.raises(ValueError, match="different items"):
        engines.kendall_tau(["x", "y"], ["x", "z"])


def test_the_command_writes_both_files_and_refuses_a_missing_one(tmp_path, capsys):
    from experiments.analysis.render.engines import main

    for name, payload in (("mjx.json", FIRST), ("c.json", SECOND)):
        (tmp_path / name).write_text(json.dumps(payload))
    assert main(["--first", str(tmp_path / "mjx.json"), "--second", str(tmp_path / "c.json"), "--labels", "MJX,C",
                 "--out", str(tmp_path / "out")]) == 0
    assert "1 of 2 tasks in the same order on MJX and C" in capsys.readouterr().out
    md = (tmp_path / "out" / "engines.md").read_text()
    assert "| Hopper | a / b | 0.87 | 0.87 |" in md
    assert "5 cells: 0 better, 1 worse, 0 equivalent, 4 inconclusive (C against MJX)." in md
    assert json.loads((tmp_path / "out" / "engines.json").read_text())["labels"] == ["MJX", "C"]
    assert main(["--first", str(tmp_path / "nope.json"), "--second", str(tmp_path / "c.json"),
                 "--out", str(tmp_path / "out")]) == 2
    assert "no such file" in capsys.readouterr().err
