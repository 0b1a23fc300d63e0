"""experiments.analysis.tables and experiments.artefacts on fabricated run folders: Table 2, the corrected verdicts,
steps to threshold, comparisons, the README and manifest ("not run" and "incomplete" cells included)."""

import csv
import json
import math
import os

import numpy as np
import pytest
from scipy import stats

from experiments import artefacts
from experiments.analysis import cells, tables
from experiments.analysis.render import tables as tables_md
from experiments.grid import methods as grid
from experiments.analysis import stats as stats_lib
from experiments.analysis.stats import fmt
from tests.helpers import fabricate_run


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
    assert tables_md.budget_text("hopper", {"meta-independent": 990_000}) == "990,000"
    assert tables_md.budget_text("reacher", {"meta-independent": 696_000, "ddpg-normal": 696_000}) == "696,000"
    assert tables_md.budget_text("hopper", {"meta-independent": 450_000, "ddpg-paramnoise": 990_000}) == \
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
    tables_md.write_table2([row], list(grid.METHODS), str(tmp_path / "out"), "", "paper")
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
    tables_md.write_table2(rows, grid.GRIDS["ddpg"], str(tmp_path / "out"), "", "paper", families=fams)
    md = (tmp_path / "out" / "table2.md").read_text()
    assert "### Against DDPG (param noise) (the grid's baseline, fixed in advance): a family of 1 comparison" in md
    assert "### Against DDPG (normal noise): a family of 2 comparisons" in md and "better noise baseline" not in md
    assert json.loads((tmp_path / "out" / "table2.json").read_text())["verdicts"][1]["baseline"] == "ddpg-normal"
    # The footer's engines: the MuJoCo cells' physics; a grid with only the JAX Pendulum stored names no MuJoCo engine.
    assert tables_md.engines_text(results.values()) == "MJX"
    pendulum_only = [results[("pendulum", "ddpg-normal")]]
    assert tables_md.engines_text(pendulum_only) == "JAX (Pendulum only: no MuJoCo cell stored)"


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
        grid.baseline_for("paper", "redq")
    assert grid.baseline_for("paper", "sac") == "sac-own"
