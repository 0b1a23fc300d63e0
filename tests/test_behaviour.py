"""experiments.analysis.behaviour: what the explorers stored, summarised from fabricated run folders."""

import json

import numpy as np
import pytest

from experiments.analysis import behaviour, cells
from experiments.analysis.render import behaviour as render_behaviour
from experiments.grid import methods as grid
from experiments.analysis.stats import fmt
from tests.helpers import fabricate_run


def test_behaviour_table_summarises_what_the_explorer_stored(tmp_path):
    """behaviour.md / .json: per finished cell that logged them, each exploration metric's first chunk (seed
    mean) and final window (the final return's: mean ± std over seeds), chunks without an ended episode left
    out; cells without the metrics (or unfinished) are not listed."""
    steps = np.arange(1, 21) * 1000
    rng = np.random.default_rng(3)
    root = tmp_path / "tuned"
    fabricate_run(root / "hopper" / "meta-independent", "hopper", "meta-independent", rng.normal(700, 50, (3, 20)), steps)
    fabricate_run(root / "hopper" / "ddpg-normal", "hopper", "ddpg-normal", rng.normal(2000, 50, (3, 20)), steps)
    fabricate_run(root / "hopper" / "ddpg-paramnoise", "hopper", "ddpg-paramnoise", rng.normal(1000, 50, (3, 20)), steps)
    train = rng.normal(15, 3, (3, 20))
    train[1, -1] = np.nan  # seed 1 ended no exploration episode in its last chunk
    log_std = rng.normal(-0.5, 0.1, (3, 20))
    for method, extra in (("meta-independent", {"train_return": train, "teacher_log_std": log_std}),
                          ("ddpg-normal", {"train_return": train + 1000})):
        path = root / "hopper" / method / "metrics.jsonl"
        rows = [json.loads(line) for line in path.read_text().splitlines()]
        for r in rows:
            for k, v in extra.items():
                x = v[r["seed"], r["chunk"]]
                r[k] = None if np.isnan(x) else float(x)
        path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    results = cells.collect(str(root), ["hopper"])
    rows = {r["method"]: r for r in behaviour.behaviour_rows(results, ["hopper"], list(grid.METHODS))}
    assert set(rows) == {"meta-independent", "ddpg-normal"}  # param noise logged no exploration metric
    meta = rows["meta-independent"]
    final_train = np.array([train[0, -2:].mean(), train[1, -2], train[2, -2:].mean()])  # 20 chunks: the last 2
    assert meta["train_return"]["first"] == pytest.approx(train[:, 0].mean())
    assert meta["train_return"]["final_mean"] == pytest.approx(final_train.mean())
    assert meta["train_return"]["final_std"] == pytest.approx(final_train.std(ddof=1))
    assert meta["teacher_log_std"]["final_mean"] == pytest.approx(log_std[:, -2:].mean())
    assert "teacher_student_distance" not in meta and "teacher_log_std" not in rows["ddpg-normal"]
    assert meta["eval_final"] == pytest.approx(results[("hopper", "meta-independent")].final().mean())
    render_behaviour.write_behaviour(list(rows.values()), str(tmp_path), "", "tuned")
    md = (tmp_path / "behaviour.md").read_text()
    line = next(x for x in md.splitlines() if x.startswith("| Meta (independent) |"))
    assert f"| {fmt(train[:, 0].mean())} | {fmt(final_train.mean())} ± {fmt(final_train.std(ddof=1))} |" in line
    assert line.endswith("| – | – | – | – |") and "## Hopper" in md
    assert json.loads((tmp_path / "behaviour.json").read_text())["rows"][0]["method"] == "meta-independent"
