"""experiments.artefacts (and its stats / cells / tables / figures) / experiments.reproduce / the
teacher-design notebook.

* statistics helpers against formulas written out here;
* the artefact builders on fabricated run folders (numbers, "not run" and "incomplete" cells, figures);
* ``experiments.reproduce`` end to end on a tiny pendulum grid (run, skip what is done, resume);
* the notebook, tiny mode, executed top to bottom with nbclient.
"""

import csv
import json
import math
import os
import shutil
import sys

import numpy as np
import pytest
from scipy import stats

from experiments import artefacts, cells, figures, grid, reproduce, tables
from experiments import stats as stats_lib
from experiments.stats import (final_returns, first_step_reaching, fmt, mean_std, num_final_evaluations,
                               t_interval, welch_difference, welch_test)
from tests.helpers import fabricate_run

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# The same settings as tests/test_screen.py's, with a fixed replay capacity: the two files' pendulum cells of
# the same method run one program whatever their budget (the session's compile cache compiles it once).
TINY = ["--set", "run.eval_every=300", "--set", "ddpg.hidden=16,16", "--set", "meta.hidden=16,16",
        "--set", "run.eval_episodes=2", "--set", "meta.visit_samples=64", "--set", "ddpg.batch_size=16",
        "--set", "run.buffer_size=900"]


# ---------------------------------------------------------------------------------------------- statistics

def test_final_returns_use_the_last_tenth_at_least_one():
    assert [num_final_evaluations(t) for t in (1, 5, 9, 10, 19, 20, 100, 167)] == [1, 1, 1, 1, 1, 2, 10, 16]
    values = np.arange(2 * 20, dtype=float).reshape(2, 20)
    np.testing.assert_allclose(final_returns(values), [(18 + 19) / 2, (38 + 39) / 2])
    np.testing.assert_allclose(final_returns(values[:, :3]), [2, 22])


def test_run_summary_is_the_tables_final_return_with_the_last_evaluation_apart():
    """summary.json's numbers (experiments.stats.run_summary): the mean of each seed's last 10% of
    evaluations, mean ± sample std over seeds; the last evaluation alone under its own name."""
    from experiments.stats import describe_final, run_summary

    values = np.arange(2 * 20, dtype=float).reshape(2, 20)  # finals 18.5 and 38.5
    s = run_summary(np.arange(1, 21) * 100, values)
    assert s["env_steps"] == 2000 and s["num_seeds"] == 2 and s["final_return_evaluations"] == 2
    assert s["final_return_per_seed"] == [18.5, 38.5] and s["final_return_mean"] == 28.5
    assert s["final_return_std"] == pytest.approx(np.sqrt(2 * 10.0 ** 2))  # sample std of 18.5, 38.5
    assert s["last_eval_return_per_seed"] == [19.0, 39.0] and s["last_eval_return_mean"] == 29.0
    assert describe_final(s) == ("final return 28.5 ± 14.1 (mean of the last 2 evaluations per seed; mean ± "
                                 "sample std over 2 seeds)")
    values[1, -1] = np.nan  # a seed without a finite last evaluation: None in JSON, not NaN
    assert run_summary(np.arange(1, 21), values)["last_eval_return_per_seed"] == [19.0, None]


def test_mean_std_t_interval_and_welch_match_the_formulas():
    a = np.array([1.0, 2.5, 4.0, 3.5])
    b = np.array([0.5, 1.0, 0.0])
    mean, std = mean_std(a)
    assert mean == pytest.approx(a.sum() / 4)
    assert std == pytest.approx(math.sqrt(((a - a.mean()) ** 2).sum() / 3))
    _, half = t_interval(a)
    assert half == pytest.approx(stats.t.ppf(0.975, 3) * std / math.sqrt(4))
    # Welch: t = (ma - mb) / sqrt(va/na + vb/nb), Welch-Satterthwaite df, two-sided p.
    va, vb = a.var(ddof=1) / 4, b.var(ddof=1) / 3
    t = (a.mean() - b.mean()) / math.sqrt(va + vb)
    df = (va + vb) ** 2 / (va ** 2 / 3 + vb ** 2 / 2)
    got_t, got_p = welch_test(a, b)
    assert got_t == pytest.approx(t) and got_p == pytest.approx(2 * stats.t.sf(abs(t), df))
    assert all(math.isnan(v) for v in welch_test(a, b[:1]))
    # The difference's Welch interval: t(0.975, df) * sqrt(va/na + vb/nb), scipy's own interval too.
    diff, half = welch_difference(a, b)
    assert diff == pytest.approx(a.mean() - b.mean())
    assert half == pytest.approx(stats.t.ppf(0.975, df) * math.sqrt(va + vb))
    ci = stats.ttest_ind(a, b, equal_var=False).confidence_interval(0.95)
    assert (diff - half, diff + half) == pytest.approx((ci.low, ci.high))
    assert math.isnan(welch_difference(a, b[:1])[1])
    assert math.isnan(t_interval([3.0])[1]) and math.isnan(mean_std([3.0])[1])


def test_first_step_reaching():
    steps = np.array([100, 200, 300, 400])
    assert first_step_reaching(steps, np.array([0.0, np.nan, 5.0, 7.0]), 5.0) == 300
    assert first_step_reaching(steps, np.array([0.0, 1.0, 2.0, 3.0]), 5.0) is None


# ---------------------------------------------------------------------------------------------- fabricated runs

@pytest.fixture(scope="module")
def fabricated(tmp_path_factory):
    """A paper-preset grid: IDP with three methods (ddpg-normal not run), pendulum meta incomplete."""
    root = tmp_path_factory.mktemp("grid")
    rng = np.random.default_rng(0)
    steps = np.arange(1, 21) * 1000
    ramp = np.linspace(0.0, 1.0, 20)
    data = {
        "meta-independent": 8000 * ramp ** 0.3 + rng.normal(0, 300, (3, 20)),
        "meta-variance": 6000 * ramp + rng.normal(0, 300, (2, 20)),
        "ddpg-paramnoise": 3000 * ramp + rng.normal(0, 500, (4, 20)),
    }
    for method, values in data.items():
        fabricate_run(root / "paper" / "inverted_double_pendulum" / method, "inverted_double_pendulum", method,
                      values, steps, visit_obs=9)
    fabricate_run(root / "paper" / "pendulum" / "meta-independent", "pendulum", "meta-independent",
                  rng.normal(-500, 50, (2, 5)), steps[:5], complete=False)
    results = root / "results"
    manifest = artefacts.build_all(str(root), str(results), "paper", embedding="pca", points_per_panel=60)
    return {"root": root, "results": results, "data": data, "steps": steps, "manifest": manifest}


def test_training_seconds_add_up_every_call():
    from metapg_jax.host import metric_rows

    def rows(walls, chunk_seconds=None, seeds=2):
        return [{"seed": s, "chunk": c, "wall_time": w, **({} if chunk_seconds is None else
                                                              {"chunk_seconds": chunk_seconds[c]})}
                for c, w in enumerate(walls) for s in range(seeds)]

    # older rows (wall_time only): a call of 3 chunks, killed, resumed for 2 (its clock restarts at 0)
    assert metric_rows.training_seconds(rows([10.0, 20.0, 30.0, 5.0, 15.0])) == (45.0, False)
    # rows with chunk_seconds add up exactly, also where the clock restart is invisible in wall_time
    exact = rows([10.0, 40.0, 50.0], chunk_seconds=[10.0, 40.0, 10.0])
    assert metric_rows.training_seconds(exact) == (60.0, True)
    assert metric_rows.training_seconds([{"seed": 0, "chunk": 0}]) == (None, False)


def test_table2_numbers_match_hand_computation(fabricated):
    table = json.loads((fabricated["results"] / "table2.json").read_text())
    row = next(r for r in table["rows"] if r["task"] == "inverted_double_pendulum")
    finals = {}
    for method, values in fabricated["data"].items():
        final = values[:, -2:].mean(1)  # 20 evaluations: the last 2
        finals[method] = final
        cell = row["methods"][method]
        n = len(final)
        s = math.sqrt(((final - final.mean()) ** 2).sum() / (n - 1))
        assert cell["status"] == "done" and cell["n"] == n and cell["budget"] == 20000
        assert cell["mean"] == pytest.approx(final.mean())
        assert cell["std"] == pytest.approx(s)
        assert cell["ci95_half_width"] == pytest.approx(stats.t.ppf(0.975, n - 1) * s / math.sqrt(n))
        np.testing.assert_allclose(cell["per_seed"], final)
    a, b = finals["meta-independent"], finals["ddpg-paramnoise"]
    va, vb = a.var(ddof=1) / len(a), b.var(ddof=1) / len(b)
    t = (a.mean() - b.mean()) / math.sqrt(va + vb)
    df = (va + vb) ** 2 / (va ** 2 / (len(a) - 1) + vb ** 2 / (len(b) - 1))
    assert row["welch"]["p"] == pytest.approx(2 * stats.t.sf(abs(t), df))
    assert "ddpg-normal" not in row["methods"]  # no cell of it anywhere: left out, not "not run"
    assert row["methods"]["meta-variance"]["status"] == "done"
    pend = next(r for r in table["rows"] if r["task"] == "pendulum")
    assert pend["methods"]["meta-independent"]["status"] == "incomplete" and pend["welch"] is None

    md = (fabricated["results"] / "table2.md").read_text()
    idp_line = next(line for line in md.splitlines() if line.startswith("| InvertedDoublePendulum |"))
    assert "not run" not in idp_line and "7,718 ± 277" in idp_line and "2,795 ± 1,325" in idp_line
    pend_line = next(line for line in md.splitlines() if line.startswith("| Pendulum |"))
    assert pend_line.count("not run") == 2  # meta-variance and param noise: planned, shown, not run there
    assert "| 20,000 (reduced; paper: 1,500,000) |" in idp_line  # tiny budget: flagged
    # the paper budget rounded down to whole evaluation intervals is not a reduction; anything less is
    assert tables.budget_text("hopper", {"meta-independent": 990_000}) == "990,000"
    assert tables.budget_text("reacher", {"meta-independent": 696_000, "ddpg-normal": 696_000}) == "696,000"
    assert tables.budget_text("hopper", {"meta-independent": 450_000, "ddpg-paramnoise": 990_000}) == \
        "Meta (independent): 450,000; DDPG (param noise): 990,000 (reduced; paper: 1,000,000)"
    assert "incomplete (5,000 of 15,000 steps)" in md
    assert "| Hopper |" not in md and "| Reacher |" not in md  # tasks with no cell stored: left out
    assert "DDPG (normal noise)" not in md
    assert "last max(1, floor(T/10)) evaluations" in md and "Holm" in md and "commit" in md

    with open(fabricated["results"] / "table2_per_seed.csv") as f:
        per_seed = list(csv.DictReader(f))
    assert len(per_seed) == 3 + 2 + 4
    got = [float(r["final_return"]) for r in per_seed if r["method"] == "ddpg-paramnoise"]
    np.testing.assert_allclose(got, b)


def test_no_welch_test_between_cells_of_different_budgets(tmp_path):
    """Mid-extension a row can hold cells of two budgets: they are shown, but not tested against each other."""
    steps = np.arange(1, 21) * 1000
    rng = np.random.default_rng(1)
    fabricate_run(tmp_path / "paper" / "reacher" / "meta-independent", "reacher", "meta-independent",
                  rng.normal(-10, 1, (3, 20)), steps)
    fabricate_run(tmp_path / "paper" / "reacher" / "ddpg-paramnoise", "reacher", "ddpg-paramnoise",
                  rng.normal(-12, 1, (3, 10)), steps[:10])
    results = cells.collect(str(tmp_path / "paper"), ["reacher"])
    row = tables.table2_rows(results, ["reacher"], list(grid.METHODS))[0]
    assert row["methods"]["meta-independent"]["budget"] == 20000 and row["methods"]["ddpg-paramnoise"]["budget"] == 10000
    assert row["welch"] is None and row["welch_skipped"] == "budgets differ"
    comparisons = tables.comparison_rows(results, ["reacher"], list(grid.METHODS))
    assert len(comparisons["methods"]) == 2 and comparisons["pairs"] == []  # no pair across budgets either
    tables.write_table2([row], list(grid.METHODS), str(tmp_path / "out"), "", "paper")
    md = (tmp_path / "out" / "table2.md").read_text()
    assert "Reacher, Meta (independent): not compared (budgets differ)." in md


def test_steps_to_threshold(fabricated):
    steps, data = fabricated["steps"], fabricated["data"]
    threshold = data["ddpg-paramnoise"].mean(0).max()
    with open(fabricated["results"] / "steps_to_threshold.csv") as f:
        rows = {r["method"]: r for r in csv.DictReader(f) if r["task"] == "inverted_double_pendulum"}
    base_step = int(steps[np.argmax(data["ddpg-paramnoise"].mean(0) >= threshold)])
    meta_step = int(steps[np.argmax(data["meta-independent"].mean(0) >= threshold)])
    assert float(rows["meta-independent"]["threshold"]) == pytest.approx(threshold)
    assert int(rows["ddpg-paramnoise"]["step"]) == base_step
    assert int(rows["meta-independent"]["step"]) == meta_step
    assert float(rows["meta-independent"]["ratio"]) == pytest.approx(meta_step / base_step)
    assert "Samples to reach" in (fabricated["results"] / "steps_to_threshold.md").read_text()


def test_comparisons_match_hand_computation(fabricated):
    steps, data = fabricated["steps"], fabricated["data"]
    comp = json.loads((fabricated["results"] / "comparisons.json").read_text())
    cells = {r["method"]: r for r in comp["methods"] if r["task"] == "inverted_double_pendulum"}
    assert set(cells) == set(data)  # finished cells only: the incomplete pendulum cell is left out
    assert {r["task"] for r in comp["methods"]} == {"inverted_double_pendulum"}
    for method, values in data.items():
        final, curve = values[:, -2:].mean(1), values.mean(0)
        c = cells[method]
        assert c["median"] == pytest.approx(np.median(final)) and c["n"] == len(final)
        assert (c["min"], c["max"]) == (pytest.approx(final.min()), pytest.approx(final.max()))
        assert c["best_seed_mean"] == pytest.approx(curve.max())
        assert c["best_seed_mean_step"] == int(steps[curve.argmax()])
        assert c["mean_over_evaluations"] == pytest.approx(curve.mean())
    pairs = {(p["a"], p["b"]): p for p in comp["pairs"]}
    # every pair once, in the grid's method order
    assert set(pairs) == {("meta-independent", "meta-variance"), ("meta-independent", "ddpg-paramnoise"),
                          ("meta-variance", "ddpg-paramnoise")}
    for (a, b), p in pairs.items():
        fa, fb = data[a][:, -2:].mean(1), data[b][:, -2:].mean(1)
        va, vb = fa.var(ddof=1) / len(fa), fb.var(ddof=1) / len(fb)
        t = (fa.mean() - fb.mean()) / math.sqrt(va + vb)
        df = (va + vb) ** 2 / (va ** 2 / (len(fa) - 1) + vb ** 2 / (len(fb) - 1))
        assert p["difference"] == pytest.approx(fa.mean() - fb.mean())
        assert p["t"] == pytest.approx(t) and p["p"] == pytest.approx(2 * stats.t.sf(abs(t), df))
        above = sum(x > y for x, y in zip(data[a].mean(0), data[b].mean(0)))
        below = sum(x < y for x, y in zip(data[a].mean(0), data[b].mean(0)))
        assert (p["a_above_b"], p["b_above_a"], p["common_evaluations"]) == (above, below, 20)
    assert 0 < pairs[("meta-independent", "ddpg-paramnoise")]["a_above_b"] < 20  # the fixture's curves cross
    md = (fabricated["results"] / "comparisons.md").read_text()
    p = pairs[("meta-independent", "ddpg-paramnoise")]
    assert f"| Meta (independent) | DDPG (param noise) | {fmt(p['difference'])} |" in md
    assert f"| {p['a_above_b']} of 20 | {p['b_above_a']} of 20 |" in md and "## InvertedDoublePendulum" in md


def test_figures_readme_and_manifest(fabricated):
    res = fabricated["results"]
    for name in ("curves_inverted_double_pendulum.png", "curves_pendulum.png", "teacher_designs_idp.png",
                 "comparisons.md", "behaviour.md", "visitation_inverted_double_pendulum.png", "README.md",
                 "manifest.json"):
        assert (res / name).exists() and (res / name).stat().st_size > 0, name
    assert (res / "visitation_inverted_double_pendulum.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    manifest = json.loads((res / "manifest.json").read_text())
    assert {c["method"] for c in manifest["cells"] if c["task"] == "inverted_double_pendulum"} == \
        {"meta-independent", "meta-variance", "ddpg-paramnoise"}
    assert manifest["not_run"] == [["pendulum", "meta-variance"], ["pendulum", "ddpg-paramnoise"]]
    assert manifest["grid_without_cells"] == {"tasks": ["inverted_pendulum", "hopper", "halfcheetah", "reacher"],
                                              "methods": ["ddpg-normal"]}
    readme = (res / "README.md").read_text()
    assert "Left out of the tables (the grid has no cell stored for them): InvertedPendulum, Hopper, HalfCheetah, " \
           "Reacher; DDPG (normal noise)." in readme
    # the aggregate needs every method on a task: Pendulum's Meta is unfinished, so only IDP enters
    agg = json.loads((res / "aggregate.json").read_text())
    assert agg["tasks"] == ["inverted_double_pendulum"] and agg["built"]["grid"] == "table2.json"
    assert {"aggregate.md", "performance_profiles.png", "coverage.md", "coverage.json"} <= set(manifest["files"])
    cov = json.loads((res / "coverage.json").read_text())
    assert {(r["phase"], r["group"]) for r in cov["rows"]} == {(w, g) for w in ("early", "late")
                                                               for g in ("teacher", "student", "ddpg")}
    cell = next(c for c in manifest["cells"] if c["method"] == "ddpg-paramnoise")
    assert cell["seeds"] == 4 and cell["budget_env_steps"] == 20000 and cell["wall_seconds"] == pytest.approx(2.0)
    assert manifest["build"]["machine"]["cpu_count"] == os.cpu_count()
    assert "teacher_designs_idp.png" in (res / "README.md").read_text()


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
    rows = {r["method"]: r for r in tables.behaviour_rows(results, ["hopper"], list(grid.METHODS))}
    assert set(rows) == {"meta-independent", "ddpg-normal"}  # param noise logged no exploration metric
    meta = rows["meta-independent"]
    final_train = np.array([train[0, -2:].mean(), train[1, -2], train[2, -2:].mean()])  # 20 chunks: the last 2
    assert meta["train_return"]["first"] == pytest.approx(train[:, 0].mean())
    assert meta["train_return"]["final_mean"] == pytest.approx(final_train.mean())
    assert meta["train_return"]["final_std"] == pytest.approx(final_train.std(ddof=1))
    assert meta["teacher_log_std"]["final_mean"] == pytest.approx(log_std[:, -2:].mean())
    assert "teacher_student_distance" not in meta and "teacher_log_std" not in rows["ddpg-normal"]
    assert meta["eval_final"] == pytest.approx(results[("hopper", "meta-independent")].final().mean())
    tables.write_behaviour(list(rows.values()), str(tmp_path), "", "tuned")
    md = (tmp_path / "behaviour.md").read_text()
    line = next(x for x in md.splitlines() if x.startswith("| Meta (independent) |"))
    assert f"| {fmt(train[:, 0].mean())} | {fmt(final_train.mean())} ± {fmt(final_train.std(ddof=1))} |" in line
    assert line.endswith("| – | – | – | – |") and "## Hopper" in md
    assert json.loads((tmp_path / "behaviour.json").read_text())["rows"][0]["method"] == "meta-independent"


def test_table2_judges_every_teacher_against_every_noise_baseline_with_holm(tmp_path):
    """One family per noise baseline, the grid's own first: every teacher against it on every task where both
    finished; Welch p Holm-corrected within the family, the TOST of the anchors' margin beside it, and the
    verdict words; no baseline is picked by its mean."""
    rng = np.random.default_rng(3)
    steps = np.arange(1, 11) * 1000
    data = {"hopper": {"meta-independent": rng.normal(900, 30, (4, 10)), "ddpg-paramnoise": rng.normal(500, 40, (4, 10)),
                       "ddpg-normal": rng.normal(700, 40, (4, 10))},
            "reacher": {"meta-independent": rng.normal(-10, 1, (4, 10)), "ddpg-normal": rng.normal(-10.2, 1, (4, 10))},
            "pendulum": {"ddpg-normal": rng.normal(-200, 10, (4, 10))}}
    results = {}
    for task, cells_ in data.items():
        for method, values in cells_.items():
            fabricate_run(tmp_path / task / method, task, method, values, steps)
            results[(task, method)] = cells.load_run(str(tmp_path / task / method), task, method)
    rows = tables.table2_rows(results, list(data), grid.GRIDS["ddpg"])
    anchors = {"hopper": (0.0, 1000.0), "reacher": (-40.0, -4.0)}
    fams = tables.verdict_families(rows, grid.GRIDS["ddpg"], "ddpg-paramnoise", anchors)
    assert [f["baseline"] for f in fams] == ["ddpg-paramnoise", "ddpg-normal"]
    assert fams[0]["fixed_in_advance"] and not fams[1]["fixed_in_advance"]
    assert [(c["task"], c["method"]) for c in fams[0]["comparisons"]] == [("hopper", "meta-independent")]
    normal = {c["task"]: c for c in fams[1]["comparisons"]}
    assert set(normal) == {"hopper", "reacher"}  # pendulum has no teacher
    finals = lambda t, m: data[t][m][:, -1]
    raw = [stats.ttest_ind(finals(t, "meta-independent"), finals(t, "ddpg-normal"), equal_var=False).pvalue
           for t in ("hopper", "reacher")]
    assert [normal[t]["p"] for t in ("hopper", "reacher")] == pytest.approx(raw)
    assert [normal[t]["p_holm"] for t in ("hopper", "reacher")] == pytest.approx(list(stats_lib.holm(raw)))
    assert normal["hopper"]["verdict"] == "better" and normal["reacher"]["margin"] == pytest.approx(0.05 * 36)
    a, b = finals("hopper", "meta-independent"), finals("hopper", "ddpg-normal")
    ci = stats.ttest_ind(a, b, equal_var=False).confidence_interval(0.95)
    assert normal["hopper"]["ci95"] == pytest.approx([ci.low, ci.high])
    assert normal["reacher"]["verdict"] in ("inconclusive", "equivalent")
    assert normal["reacher"]["verdict"] == ("equivalent" if normal["reacher"]["p_equivalence_holm"] < 0.05
                                            else "inconclusive")
    tables.write_table2(rows, grid.GRIDS["ddpg"], str(tmp_path / "out"), "", "paper", families=fams)
    md = (tmp_path / "out" / "table2.md").read_text()
    assert "### Against DDPG (param noise) (the grid's baseline, fixed in advance): a family of 1 comparison" in md
    assert "### Against DDPG (normal noise): a family of 2 comparisons" in md and "better noise baseline" not in md
    assert json.loads((tmp_path / "out" / "table2.json").read_text())["verdicts"][1]["baseline"] == "ddpg-normal"
    # The footer's engines: the MuJoCo cells' physics; a grid with only the JAX Pendulum stored names no MuJoCo engine.
    assert tables.engines_text(results.values()) == "MJX"
    assert "MJX" not in tables.engines_text([results[("pendulum", "ddpg-normal")]])


def test_modern_preset_compares_meta_with_its_own_gaussian_noise_ddpg(tmp_path):
    """The modern preset's baseline is DDPG (normal noise): Welch test, thresholds and visitation use it."""
    rng = np.random.default_rng(1)
    steps = np.arange(1, 11) * 1000
    data = {"meta-independent": rng.normal(900, 30, (3, 10)), "ddpg-normal": rng.normal(500, 40, (3, 10)),
            "ddpg-paramnoise": rng.normal(100, 40, (3, 10))}
    for method, values in data.items():
        fabricate_run(tmp_path / "modern" / "hopper" / method, "hopper", method, values, steps, visit_obs=11)
    results = tmp_path / "results"
    artefacts.build_all(str(tmp_path), str(results), "modern", tasks=("hopper",), embedding="pca",
                        points_per_panel=40)
    table = json.loads((results / "modern" / "table2.json").read_text())
    assert table["baseline"] == "ddpg-normal"
    a, b = data["meta-independent"][:, -1], data["ddpg-normal"][:, -1]
    assert table["rows"][0]["welch"]["p"] == pytest.approx(stats.ttest_ind(a, b, equal_var=False).pvalue)
    md = (results / "modern" / "table2.md").read_text()
    assert "### Against DDPG (normal noise) (the grid's baseline, fixed in advance)" in md and "for scale only" in md
    with open(results / "modern" / "steps_to_threshold.csv") as f:
        rows = list(csv.DictReader(f))
    assert float(rows[0]["threshold"]) == pytest.approx(data["ddpg-normal"].mean(0).max())
    assert (results / "modern" / "visitation_hopper.png").exists()
    archive = results / "modern" / "cells" / "hopper"
    assert (archive / "ddpg-normal" / "visits.npz").exists()
    assert not (archive / "ddpg-paramnoise" / "visits.npz").exists()
    with pytest.raises(ValueError, match="unknown preset"):
        grid.baseline_for("fancy")


def test_visitation_groups_keep_only_recorded_states():
    v = {f"{w}_{t}": np.ones((2, 5, 3)) for w in ("explore", "student") for t in ("early", "late")}
    teacher = {**v, "explore_count": np.array([3, 10]), "student_count": np.array([5, 5])}
    ddpg = {**v, "explore_count": np.array([10, 10]), "student_count": np.array([0, 0])}
    groups = figures.visitation_groups(teacher, ddpg)
    assert groups[("early", "teacher")].shape == (3 + 5, 3)
    assert groups[("late", "student")].shape == (10, 3)
    assert groups[("early", "ddpg")].shape == (10, 3)


def test_embeddings_give_two_columns():
    x = np.random.default_rng(0).normal(size=(60, 4))
    for method in ("pca", "tsne"):
        assert figures.embed_2d(x, method).shape == (60, 2)
    assert figures.embed_2d(x[:, :1], "pca").shape == (60, 2)
    with pytest.raises(ValueError, match="unknown embedding"):
        figures.embed_2d(x, "umap")


# ---------------------------------------------------------------------------------------------- reproduce

def test_reproduce_rejects_bad_input(capsys):
    assert reproduce.main(["--tasks", "cartpole"]) == 2
    assert "unknown task 'cartpole'" in capsys.readouterr().err
    assert reproduce.main(["--methods", "sac"]) == 2
    assert reproduce.main(["--seeds", "0"]) == 2


def test_reproduce_checks_every_cell_before_the_first_runs(tmp_path, capsys):
    """1000 steps fit DDPG's 100-step cycle but not Meta's 300 on pendulum: refused before DDPG trains."""
    runs = tmp_path / "runs"
    base = ["--tasks", "pendulum", "--runs-dir", str(runs), "--results-dir", str(tmp_path / "results")]
    assert reproduce.main([*base, "--methods", "ddpg-paramnoise,meta-independent", "--steps", "1000"]) == 2
    err = capsys.readouterr().err
    assert "pendulum/meta-independent:" in err and "not a multiple of the 300 env steps" in err
    assert reproduce.main([*base, "--set", "ddpg.nope=1", "--dry-run"]) == 2
    assert "unknown config field 'ddpg.nope'" in capsys.readouterr().err
    assert not runs.exists()
    # A cell finished at (at least) the requested budget is skipped, so its config at that budget is not checked.
    cell = runs / "paper" / "pendulum" / "meta-independent"
    fabricate_run(cell, "pendulum", "meta-independent", np.zeros((2, 4)), np.arange(1, 5) * 300)
    summary = json.loads((cell / "summary.json").read_text())
    (cell / "summary.json").write_text(json.dumps({**summary, "final_return_mean": 0.0,
                                                   "final_return_std": 0.0}))
    assert reproduce.main([*base, "--methods", "ddpg-paramnoise,meta-independent", "--steps", "1000",
                           "--dry-run"]) == 0
    assert "grid: 1 skipped, 1 would new" in capsys.readouterr().out


def test_reproduce_tiny_grid_runs_skips_and_resumes(tmp_path, capsys):
    runs, results = tmp_path / "runs", tmp_path / "results"
    argv = ["--tasks", "pendulum", "--methods", "meta-independent,ddpg-paramnoise", "--seeds", "2", "--steps", "600",
            "--runs-dir", str(runs), "--results-dir", str(results), "--embedding", "pca", "--quiet", "--no-plot",
            *TINY]
    assert reproduce.main(argv + ["--dry-run"]) == 0
    assert "running: python -m experiments.run --env=pendulum --method=meta" in capsys.readouterr().out
    assert not runs.exists()

    assert reproduce.main(argv) == 0
    out = capsys.readouterr().out
    assert "grid: 2 ran" in out
    for method in ("meta-independent", "ddpg-paramnoise"):
        cell = runs / "paper" / "pendulum" / method
        assert (cell / "summary.json").exists() and (cell / "reproduce.json").exists()
        rec = json.loads((cell / "reproduce.json").read_text())
        assert rec["calls"][0]["status"] == 0 and rec["machine"]["cpu_count"] == os.cpu_count()
    table = json.loads((results / "table2.json").read_text())
    pend = next(r for r in table["rows"] if r["task"] == "pendulum")
    summary = json.loads((runs / "paper" / "pendulum" / "ddpg-paramnoise" / "summary.json").read_text())
    # 2 evaluations: the final return is the last one, as in summary.json.
    np.testing.assert_allclose(pend["methods"]["ddpg-paramnoise"]["per_seed"],
                               summary["final_return_per_seed"], rtol=1e-6)
    assert "meta-variance" not in pend["methods"] and pend["welch"] is not None  # planned, never run: left out
    assert json.loads((results / "manifest.json").read_text())["grid_without_cells"]["methods"] == \
        ["meta-variance", "ddpg-normal"]
    for name in ("table2.md", "table2_per_seed.csv", "curves_pendulum.png", "steps_to_threshold.csv",
                 "visitation_pendulum.png", "README.md", "manifest.json"):
        assert (results / name).exists(), name

    # Second call: nothing to run, artefacts rebuilt.
    (results / "table2.md").unlink()
    assert reproduce.main(argv) == 0
    out = capsys.readouterr().out
    assert out.count("done, skipped") == 2 and "grid: 2 skipped" in out and "stored budget" not in out
    assert (results / "table2.md").exists()
    # Without --steps the paper's budget is asked for: the finished 600-step cells would be extended.
    no_steps = [a for a in argv if a not in ("--steps", "600")]
    assert reproduce.main(no_steps + ["--dry-run"]) == 0
    out = capsys.readouterr().out
    assert out.count("extending from 600 to 900,000 steps: python -m experiments.run") == 2
    assert out.count("--steps=900000") == 2 and "grid: 2 would extend" in out
    # A cell whose evaluation interval is not the one a run at the requested budget gets is not extended.
    assert reproduce.main(argv + ["--steps", "1200", "--set", "run.eval_every=600", "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert out.count("its evaluation interval 300 is not the 600 of a run at that budget") == 2
    assert "grid: 2 skipped" in out

    # A cell with a checkpoint but no summary is resumed (with the same explicit options).
    (runs / "paper" / "pendulum" / "ddpg-paramnoise" / "summary.json").unlink()
    assert reproduce.main(argv + ["--methods", "ddpg-paramnoise"]) == 0
    out = capsys.readouterr().out
    assert "resuming: python -m experiments.run" in out and "grid: 1 resumed" in out
    assert (runs / "paper" / "pendulum" / "ddpg-paramnoise" / "summary.json").exists()
    rec = json.loads((runs / "paper" / "pendulum" / "ddpg-paramnoise" / "reproduce.json").read_text())
    calls = rec["calls"]
    assert len(calls) == 2 and "--resume" in calls[1]["argv"]
    # Each call records the commit it ran; the cell's commit is the one it was started at (config.json's).
    started = json.loads((runs / "paper" / "pendulum" / "ddpg-paramnoise" / "config.json").read_text())["commit"]
    assert rec["commit"] == calls[0]["commit"] == started and rec["commits"] == sorted({c["commit"] for c in calls})
    assert rec["wall_seconds"] == pytest.approx(sum(c["wall_seconds"] for c in calls), abs=0.02)
    # A first call killed before writing its record: the cell's commit is still config.json's.
    cell = runs / "paper" / "pendulum" / "ddpg-paramnoise"
    (cell / "reproduce.json").unlink()
    cfg = json.loads((cell / "config.json").read_text())
    (cell / "config.json").write_text(json.dumps({**cfg, "commit": "0" * 40, "dirty": False}))
    reproduce._write_cell_record(str(cell), ["--resume"], 0, 1.0, {"commit": "f" * 40, "dirty": True})
    rec = json.loads((cell / "reproduce.json").read_text())
    assert rec["commit"] == "0" * 40 and rec["dirty"] is False and rec["commits"] == ["0" * 40, "f" * 40]
    assert rec["calls"][0]["commit"] == "f" * 40 and rec["wall_seconds"] == 1.0
    (cell / "config.json").write_text(json.dumps(cfg))

    # A larger --steps extends a finished cell from its last checkpoint; the archive gets the longer cell.
    assert reproduce.main(argv + ["--methods", "ddpg-paramnoise", "--steps", "900"]) == 0
    out = capsys.readouterr().out
    assert "extending from 600 to 900 steps" in out and "grid: 1 extended" in out
    assert json.loads((cell / "summary.json").read_text())["env_steps"] == 900
    assert json.loads((results / "cells" / "pendulum" / "ddpg-paramnoise" / "summary.json").read_text())[
        "env_steps"] == 900
    last = json.loads((cell / "reproduce.json").read_text())["calls"][-1]["argv"]
    assert "--steps=900" in last and last[-2:] == ["--resume", str(cell)]
    assert (cell / "summary_600.json").exists()
    # A finished shorter cell whose checkpoints/ is empty has nothing to extend from: skipped with a note.
    os.rename(cell / "checkpoints", cell / "checkpoints.moved")
    (cell / "checkpoints").mkdir()
    assert reproduce.main(argv + ["--methods", "ddpg-paramnoise", "--steps", "1200", "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "is below the requested 1,200, and no checkpoint to extend it from is stored" in out
    assert "grid: 1 skipped" in out
    (cell / "checkpoints").rmdir()
    os.rename(cell / "checkpoints.moved", cell / "checkpoints")

    # A fresh clone: no run folders, only the committed archive. Nothing is rerun and the table is the same.
    archived = results / "cells" / "pendulum" / "ddpg-paramnoise"
    assert (archived / "summary.json").exists() and (archived / "metrics.jsonl").exists()
    with np.load(archived / "visits.npz") as v:
        assert v["explore_late"].shape[-2] <= cells.ARCHIVE_VISITS_PER_SEED
    before = json.loads((results / "table2.json").read_text())["rows"]
    shutil.rmtree(runs)
    assert reproduce.main(argv) == 0
    out = capsys.readouterr().out
    assert out.count("done, skipped") == 2 and "grid: 2 skipped" in out and not runs.exists()
    assert "stored budget 900 is above the requested 600" in out
    assert reproduce.main(argv + ["--steps", "1200", "--dry-run"]) == 0
    assert capsys.readouterr().out.count("is below the requested 1,200, and no checkpoint to extend it from is "
                                         "stored") == 2
    after = json.loads((results / "table2.json").read_text())["rows"]
    strip = lambda rows: [{m: {k: v for k, v in c.items() if k != "run_dir"} for m, c in r["methods"].items()}
                          for r in rows]
    assert strip(after) == strip(before)
    assert "results/cells/pendulum/meta-independent" in next(
        r for r in after if r["task"] == "pendulum")["methods"]["meta-independent"]["run_dir"]
    assert (results / "visitation_pendulum.png").exists()

    # Artefacts only, modern preset: nothing stored there, so no row or column, the README says why; own folder.
    assert reproduce.main(["--artefacts-only", "--preset", "modern", "--runs-dir", str(runs),
                           "--results-dir", str(results)]) == 0
    md = (results / "modern" / "table2.md").read_text()
    assert "modern preset" in md and "| Pendulum |" not in md
    readme = (results / "modern" / "README.md").read_text()
    assert "Left out of the tables (the grid has no cell stored for them): InvertedDoublePendulum" in readme
    assert "No aggregate scores" in readme and not (results / "modern" / "aggregate.md").exists()


# ---------------------------------------------------------------------------------------------- notebook

def test_teacher_designs_notebook_runs_in_tiny_mode(monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    from jupyter_client.kernelspec import KernelSpecManager

    if "python3" not in KernelSpecManager().find_kernel_specs():
        pytest.skip("no python3 kernel spec (pip install ipykernel)")
    monkeypatch.setenv("NOTEBOOK_SIZE", "tiny")
    monkeypatch.setenv("JAX_PLATFORMS", "cpu")
    monkeypatch.setenv("PYTHONPATH", ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    path = os.path.join(ROOT, "experiments", "notebooks", "teacher_designs.ipynb")
    nb = nbformat.read(path, as_version=4)
    first = next(c for c in nb.cells if c.cell_type == "code")
    assert 'SIZE = os.environ.get("NOTEBOOK_SIZE", "tiny")' in first.source
    nbclient.NotebookClient(nb, timeout=300, kernel_name="python3",
                            resources={"metadata": {"path": ROOT}}).execute()
    text = "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", []))
    assert "swept values are live: ok" in text
    images = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
              if o.get("output_type") == "display_data" and "image/png" in o.get("data", {})]
    assert len(images) >= 3


def test_a_visitation_figure_per_task_with_both_samples(tmp_path):
    """Every task whose Meta (independent) and DDPG baseline cells stored visited states gets a figure
    (default); --visitation-task restricts it; a task without the DDPG cell gets none."""
    rng = np.random.default_rng(2)
    steps = np.arange(1, 6) * 1000
    for task, obs, methods in (("pendulum", 3, ("meta-independent", "ddpg-paramnoise")),
                               ("reacher", 10, ("meta-independent", "ddpg-paramnoise")),
                               ("hopper", 11, ("meta-independent",))):
        for method in methods:
            fabricate_run(tmp_path / "paper" / task / method, task, method, rng.normal(0, 1, (2, 5)), steps,
                          visit_obs=obs)
    tasks = ("pendulum", "reacher", "hopper")
    manifest = artefacts.build_all(str(tmp_path), str(tmp_path / "all"), "paper", tasks=tasks, embedding="pca",
                                   points_per_panel=30)
    assert sorted(f for f in manifest["files"] if f.startswith("visitation_")) == \
        ["visitation_pendulum.png", "visitation_reacher.png"]
    # Rebuilt into the same folder for one task: the other task's figure goes (it is not in the manifest).
    manifest = artefacts.build_all(str(tmp_path), str(tmp_path / "all"), "paper", tasks=tasks, embedding="pca",
                                   points_per_panel=30, visitation_tasks=["reacher", "reacher"])
    assert [f for f in manifest["files"] if f.startswith("visitation_")] == ["visitation_reacher.png"]
    assert not (tmp_path / "all" / "visitation_pendulum.png").exists()
    assert (tmp_path / "all" / "visitation_reacher.png").exists()
    with pytest.raises(SystemExit):
        artefacts.build_parser().parse_args(["--visitation-task", "cartpole"])


def test_the_td3_grid_compares_meta_on_td3_with_td3_and_gaussian_noise(tmp_path):
    """build_all(student='td3'): the baseline is TD3 (normal noise) and the titles name the student."""
    rng = np.random.default_rng(2)
    steps = np.arange(1, 11) * 1000
    data = {"meta-independent": rng.normal(900, 30, (3, 10)), "td3-normal": rng.normal(500, 40, (3, 10))}
    for method, values in data.items():
        fabricate_run(tmp_path / "paper" / "hopper" / method, "hopper", method, values, steps, visit_obs=11)
    results = tmp_path / "results"
    manifest = artefacts.build_all(str(tmp_path), str(results), "paper", tasks=("hopper",), embedding="pca",
                                   points_per_panel=40, student="td3")
    assert manifest["build"]["student"] == "td3" and manifest["not_run"] == []  # the TD3 grid's two methods
    table = json.loads((results / "table2.json").read_text())
    assert table["baseline"] == "td3-normal" and table["student"] == "td3"
    a, b = data["meta-independent"][:, -1], data["td3-normal"][:, -1]
    assert table["rows"][0]["welch"]["p"] == pytest.approx(stats.ttest_ind(a, b, equal_var=False).pvalue)
    md = (results / "table2.md").read_text()
    assert md.startswith("# Table 2: final evaluation return (paper preset, TD3 student)")
    assert "### Against TD3 (normal noise) (the grid's baseline, fixed in advance)" in md and "for scale only" in md
    assert (results / "README.md").read_text().startswith("# Results (paper preset, TD3 student)")
    assert "TD3 baseline's best" in (results / "steps_to_threshold.md").read_text()
    with open(results / "steps_to_threshold.csv") as f:
        rows = list(csv.DictReader(f))
    assert float(rows[0]["threshold"]) == pytest.approx(data["td3-normal"].mean(0).max())
    assert (results / "visitation_hopper.png").exists()
    assert (results / "cells" / "hopper" / "td3-normal" / "visits.npz").exists()
    with pytest.raises(ValueError, match="no grid for student"):
        grid.baseline_for("paper", "sac")


def test_reproduce_with_td3_runs_its_grid_in_its_own_folders(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert reproduce.main(["--tasks", "hopper", "--student", "td3", "--physics", "mujoco", "--dry-run"]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if "paper/hopper/" in line]
    assert len(lines) == 2  # meta-independent and td3-normal
    meta, noise = (next(line for line in lines if f"/{m}:" in line) for m in ("meta-independent", "td3-normal"))
    assert "--student=td3" in meta and "--method=meta" in meta and "--physics=mujoco" in meta
    assert "--out runs/reproduce-td3/paper/hopper/meta-independent" in meta
    assert "--student=td3" in noise and "--noise=normal --set noise.stddev=0.1" in noise
    assert reproduce.main(["--tasks", "hopper", "--student", "td3", "--methods", "ddpg-paramnoise", "--dry-run"]) == 2
    assert "valid: meta-independent, td3-normal" in capsys.readouterr().err
    assert not (tmp_path / "runs").exists()


def test_reproduce_on_the_c_engine_keeps_its_own_folders(tmp_path, capsys, monkeypatch):
    """--physics=mujoco: MuJoCo cells get --physics=mujoco (pendulum, a JAX task, does not), and the grid goes
    to runs/reproduce-mujoco and results/mujoco unless folders are given; brax models are refused."""
    monkeypatch.chdir(tmp_path)
    assert reproduce.main(["--tasks", "pendulum,hopper", "--methods", "meta-independent", "--physics", "mujoco",
                           "--dry-run"]) == 0
    out = capsys.readouterr().out
    hopper = next(line for line in out.splitlines() if "paper/hopper/meta-independent" in line)
    pendulum = next(line for line in out.splitlines() if "paper/pendulum/meta-independent" in line)
    assert "--physics=mujoco" in hopper and "--out runs/reproduce-mujoco/paper/hopper/meta-independent" in hopper
    assert "--physics" not in pendulum
    assert not (tmp_path / "runs").exists()
    assert reproduce.main(["--tasks", "hopper", "--physics", "mujoco", "--source", "brax", "--dry-run"]) == 2
    assert "--physics=mujoco steps gymnasium's models" in capsys.readouterr().err


def test_tensorboard_is_passed_to_every_cell_and_needs_its_extra(monkeypatch, tmp_path, capsys):
    args = reproduce.build_parser().parse_args(["--tensorboard", "--tasks", "pendulum"])
    for state in ("new", "resume", "extend"):
        assert "--tensorboard" in reproduce.cell_argv(args, "pendulum", "meta-independent", str(tmp_path), state)
    assert "--tensorboard" not in reproduce.cell_argv(reproduce.build_parser().parse_args([]), "pendulum",
                                                      "meta-independent", str(tmp_path), "new")
    monkeypatch.setitem(sys.modules, "tensorboardX", None)  # the extra not installed
    runs = tmp_path / "runs"
    assert reproduce.main(["--tensorboard", "--tasks", "pendulum", "--runs-dir", str(runs),
                           "--results-dir", str(tmp_path / "res")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "tensorboardX" in err[0] and not runs.exists()


def test_a_call_from_a_dirty_tree_stores_its_diff_and_the_tables_count_it(tmp_path):
    """A dirty call writes uncommitted-<call>.diff beside reproduce.json (named in its call entry), the archive
    keeps it, and the manifest and footer carry the dirty flag, the diffs, every commit and the engine."""
    steps = np.arange(1, 6) * 1000
    rng = np.random.default_rng(0)
    machine = {"platform": "p", "cpu_count": 2}
    outs = {}
    for method, dirty in (("meta-independent", True), ("ddpg-paramnoise", True), ("ddpg-normal", False)):
        out = tmp_path / "runs" / method
        fabricate_run(out, "hopper", method, rng.normal(0, 1, (2, 5)), steps)
        started = {"commit": f"c-{method}", "dirty": dirty, "machine": machine}
        diff = "diff --git a/x.py b/x.py\n+changed" if method == "meta-independent" else ""
        reproduce._write_cell_record(str(out), ["--a"], 0, 1.0, started, diff)
        if method == "meta-independent":  # a second, clean call (a resume) adds no diff
            reproduce._write_cell_record(str(out), ["--a"], 0, 1.0, {**started, "commit": "c-2", "dirty": False})
        if method == "ddpg-paramnoise":  # as a cell recorded before diffs were stored
            os.remove(out / "uncommitted-1.diff")
        outs[method] = out
    record = json.loads((outs["meta-independent"] / "reproduce.json").read_text())
    assert [c.get("diff") for c in record["calls"]] == ["uncommitted-1.diff", None]
    assert (outs["meta-independent"] / "uncommitted-1.diff").read_text() == "diff --git a/x.py b/x.py\n+changed\n"
    assert record["commits"] == ["c-2", "c-meta-independent"]
    archived = {}
    for method, out in outs.items():
        assert cells.archive_cell(str(out), str(tmp_path / "cells" / method), method)
        archived[method] = cells.load_run(str(tmp_path / "cells" / method), "hopper", method)
    assert (tmp_path / "cells" / "meta-independent" / "uncommitted-1.diff").exists()
    prov = {m: cells.cell_provenance(r) for m, r in archived.items()}
    assert prov["meta-independent"]["dirty"] and prov["meta-independent"]["diffs"] == ["uncommitted-1.diff"]
    assert prov["ddpg-paramnoise"]["dirty"] and prov["ddpg-paramnoise"]["diffs"] == []
    assert not prov["ddpg-normal"]["dirty"] and prov["ddpg-normal"]["physics"] == "mjx"
    assert prov["ddpg-normal"]["physics_recorded"]
    assert prov["meta-independent"]["commits"] == ["c-2", "c-meta-independent"]
    build = {"built": "now", "runs_dir": "r", "commit": "b", "dirty": False, "machine": machine}
    footer = cells.provenance_footer(build, archived.values())
    assert "`c-2`, `c-ddpg-normal`, `c-ddpg-paramnoise`, `c-meta-independent`" in footer
    assert "2 of 3 cells ran from a tree with uncommitted changes (1 without a stored diff: hopper/ddpg-paramnoise)" in footer
    assert "engines: mjx." in footer
    # a config from before the physics option ran on MJX, the only engine then: said so, not hidden
    archived["ddpg-normal"].config["env"].pop("physics")
    assert cells.cell_physics(archived["ddpg-normal"]) == ("mjx", False)
    assert "mjx inferred for cells whose config predates the physics option" in cells.provenance_footer(
        build, [archived["ddpg-normal"]])
