"""The seed rule and the "exploration matters" figure (experiments/analysis/power.py), on fabricated numbers."""

import json
import math

import numpy as np
import pytest
from scipy import stats as scipy_stats

from experiments.analysis import power


def test_ten_seeds_detect_1_3_std_uncorrected_and_2_1_std_after_holm_over_36():
    # Cohen's tables: d = 1.32 at n = 10 per group, two-sided alpha 0.05, power 0.80.
    assert power.detectable_effect(10) == pytest.approx(1.3249, abs=2e-3)
    # A family of 36 comparisons: its first Holm step tests at 0.05 / 36.
    assert power.detectable_effect(10, comparisons=36) == pytest.approx(2.108, abs=2e-3)
    assert power.power(10, power.detectable_effect(10, 36), 36) == pytest.approx(0.8, abs=1e-6)


@pytest.mark.parametrize("n,effect,comparisons", [(3, 2.0, 36), (10, 1.0, 1), (10, 2.0, 36), (100, 0.3, 36),
                                                  (300, 0.3, 36)])
def test_power_is_the_noncentral_t_tails(n, effect, comparisons):
    df, shift = 2 * (n - 1), effect / math.sqrt(2 / n)
    crit = scipy_stats.t.ppf(1 - 0.05 / comparisons / 2, df)
    expected = scipy_stats.nct.sf(crit, df, shift) + scipy_stats.nct.cdf(-crit, df, shift)
    assert power.power(n, effect, comparisons) == pytest.approx(expected, rel=1e-8, abs=1e-12)
    assert power.power(n, 30.0, comparisons) == pytest.approx(1.0)  # where scipy's nct gives NaN


def test_power_agrees_with_a_simulation_of_t_tests():
    rng = np.random.default_rng(0)
    n, effect, comparisons, reps = 8, 1.5, 4, 20_000
    a = rng.normal(0.0, 1.0, (reps, n))
    b = rng.normal(effect, 1.0, (reps, n))
    p = scipy_stats.ttest_ind(a, b, axis=1).pvalue
    simulated = float(np.mean(p < 0.05 / comparisons))
    assert power.power(n, effect, comparisons) == pytest.approx(simulated, abs=0.01)  # MC std ~0.0035


def test_the_seed_rule_takes_the_fewest_seeds_with_the_power_and_never_fewer_than_the_minimum():
    # A tenth of a range of 1,000 (delta 100) at a seed std of 120: effect 0.83 std, 36 comparisons.
    n = power.seeds_for(120.0, 100.0, comparisons=36)
    assert power.power(n, 100 / 120, 36) >= 0.8 > power.power(n - 1, 100 / 120, 36)
    assert n > 10
    assert power.seeds_for(10.0, 100.0, comparisons=36) == 10      # a large effect: the minimum holds
    assert power.seeds_for(0.0, 100.0) == 10
    assert power.seeds_for(10.0, 100.0, minimum=3) == 3              # 10 std: three seeds already detect it
    with pytest.raises(ValueError, match="needs more than 50 seeds"):
        power.seeds_for(1000.0, 10.0, maximum=50)
    for bad in ((-1.0, 1.0), (1.0, 0.0), (math.nan, 1.0)):
        with pytest.raises(ValueError, match="std must be >= 0 and delta > 0"):
            power.seeds_for(*bad)
    with pytest.raises(ValueError, match="comparisons must be a whole number"):
        power.seeds_for(1.0, 1.0, comparisons=0)


def test_exploration_matters_is_the_spread_of_entry_means_over_the_pooled_seed_std():
    grid = {"gaussian": [0.0, 2.0, 4.0],     # mean 2, variance 4
            "ou": [5.0, 6.0, 7.0],           # mean 6, variance 1
            "pink": [10.0, 12.0]}            # mean 11, variance 2
    out = power.exploration_matters(grid)
    pooled = math.sqrt((4 * 2 + 1 * 2 + 2 * 1) / 5)
    assert out["best"] == "pink" and out["worst"] == "gaussian"
    assert out["spread"] == pytest.approx(9.0)
    assert out["pooled_std"] == pytest.approx(pooled)
    assert out["figure"] == pytest.approx(9.0 / pooled)
    assert power.exploration_matters({"a": [1.0, 1.0], "b": [1.0, 1.0]})["figure"] == 0.0
    assert power.exploration_matters({"a": [1.0, 1.0], "b": [2.0, 2.0]})["figure"] == math.inf
    with pytest.raises(ValueError, match="at least two entries"):
        power.exploration_matters({"a": [1.0, 2.0]})
    with pytest.raises(ValueError, match="no entry has two seeds"):
        power.pooled_std([[1.0], [2.0]])


def _pilot(tmp_path, tasks):
    """A fabricated pilot benchmark: tasks/<task>.json with each entry's final returns per seed."""
    (tmp_path / "tasks").mkdir(parents=True)
    for task, cells in tasks.items():
        rows = [{"student": "td3", "method": m, "status": status, "per_seed": seeds}
                for m, (status, seeds) in cells.items()]
        (tmp_path / "tasks" / f"{task}.json").write_text(json.dumps({"task": task, "rows": rows}))
    return tmp_path


def test_the_seed_plan_of_a_fabricated_pilot(tmp_path, capsys):
    from experiments.analysis.render import power as render

    pilot = _pilot(tmp_path / "pilot", {
        "hopper": {"x": ("done", [0.0, 100.0, 200.0]), "y": ("done", [300.0, 400.0, 500.0]),
                   "z": ("running", [9e9, 9e9])},                                   # unfinished: not read
        "pendulum": {"x": ("done", [0.0, 0.0, 0.0]), "y": ("done", [0.0, 0.0])},   # no spread at all
        "reacher": {"x": ("done", [0.0, 1000.0]), "y": ("done", [0.0, 1000.0])},   # all seed noise
        "halfcheetah": {"x": ("done", [1.0, 2.0])}})                                 # one entry: left out
    anchors = tmp_path / "anchors.json"
    anchors.write_text(json.dumps({"tasks": {"hopper": {"random_return": 0.0, "reference_return": 1000.0},
                                             "pendulum": {"random_return": -50.0, "reference_return": 50.0},
                                             "reacher": {"random_return": 0.0, "reference_return": 1000.0}}}))
    argv = ["--results-dir", str(pilot), "--anchors", str(anchors), "--comparisons", "4", "--maximum", "40"]
    assert render.main(argv) == 0
    plan = json.loads((pilot / "seeds.json").read_text())
    rows = {r["task"]: r for r in plan["tasks"]}
    assert sorted(rows) == ["hopper", "pendulum", "reacher"]
    # Hopper: both entries' variance 100^2, so the pooled std is 100, a tenth of the range; 1 std at 0.05 / 4.
    h = rows["hopper"]
    assert h["pooled_std"] == pytest.approx(100.0) and h["delta"] == pytest.approx(100.0)
    n = h["needed"]
    assert power.power(n, 1.0, 4) >= 0.8 > power.power(n - 1, 1.0, 4) and h["seeds"] == n and not h["capped"]
    assert h["matters_spread"] == pytest.approx(300.0) and h["matters_figure"] == pytest.approx(3.0)
    assert h["spread_fraction"] == pytest.approx(0.3) and h["matters_best"] == "td3/y"
    assert h["detectable_fraction"] == pytest.approx(power.detectable_effect(n, 4) * 0.1)
    # Pendulum: no seed spread, the minimum; the figure is 0 (no entry stands out either).
    p = rows["pendulum"]
    assert p["needed"] == p["seeds"] == 10 and p["detectable_fraction"] == 0.0 and p["matters_figure"] == 0.0
    # Reacher: a seed std of 707 for a difference of 100 needs more than the cap: 40 seeds, and what they detect.
    r = rows["reacher"]
    assert r["needed"] is None and r["capped"] and r["seeds"] == 40
    assert r["detectable_fraction"] == pytest.approx(power.detectable_effect(40, 4) * np.sqrt(5e5) / 1000)
    md = (pilot / "seeds.md").read_text()
    assert "| more than 40 | 40 |" in md and f"--task-seeds hopper={n}" in md and "0.05 / 4" in md
    assert "wrote" in capsys.readouterr().out

    (tmp_path / "partial.json").write_text(json.dumps({"tasks": {"hopper": {"random_return": 0.0,
                                                                            "reference_return": 1.0}}}))
    for bad, message in ((["--anchors", str(tmp_path / "partial.json")], "no normalisation anchors"),
                         (["--results-dir", str(tmp_path)], "no tasks/ folder"),
                         (["--maximum", "5"], "must be a whole number >= minimum")):
        args = dict(zip(argv[::2], argv[1::2]))
        args.update(dict(zip(bad[::2], bad[1::2])))
        assert render.main([x for kv in args.items() for x in kv]) == 2
        assert message in capsys.readouterr().err


def test_the_projected_cost_of_a_seed_plan_from_the_pilots_cpu(tmp_path, capsys):
    """CPU per seed: each finished cell's CPU over its seeds, averaged per task (unfinished or unrecorded cells left
    out); projected hours: planned seeds x entries x that, summed against the cap."""
    from experiments.analysis.render import power as render

    cells = [{"task": "hopper", "status": "done", "seeds": 5, "cpu_seconds": 500.0},
             {"task": "hopper", "status": "done", "seeds": 10, "cpu_seconds": 2000.0},    # 100 and 200 per seed
             {"task": "hopper", "status": "running", "seeds": 5, "cpu_seconds": 9e9},
             {"task": "reacher", "status": "done", "seeds": 5, "cpu_seconds": None}]
    per_seed = power.cpu_per_seed(cells)
    assert per_seed == {"hopper": 150.0}
    rows = [{"task": "hopper", "seeds": 24}, {"task": "reacher", "seeds": 10}]
    assert power.project_cost(rows, per_seed, 5) == pytest.approx(150.0 * 24 * 5 / 3600)  # 5 h
    assert rows[0]["projected_cpu_hours"] == pytest.approx(5.0) and rows[1]["projected_cpu_hours"] is None
    with pytest.raises(ValueError, match="entries must be at least 1"):
        power.project_cost(rows, per_seed, 0)

    pilot = _pilot(tmp_path / "pilot", {"hopper": {"x": ("done", [0.0, 100.0, 200.0]),
                                                   "y": ("done", [300.0, 400.0, 500.0])}})
    anchors = tmp_path / "anchors.json"
    anchors.write_text(json.dumps({"tasks": {"hopper": {"random_return": 0.0, "reference_return": 1000.0}}}))
    argv = ["--results-dir", str(pilot), "--anchors", str(anchors), "--comparisons", "4"]
    assert render.main(argv + ["--cap-hours", "3"]) == 2 and "--cap-hours needs --entries" in capsys.readouterr().err
    assert render.main(argv + ["--entries", "3"]) == 2 and "cost.json not found" in capsys.readouterr().err
    (pilot / "cost.json").write_text(json.dumps({"cells": cells}))
    assert render.main(argv + ["--entries", "3", "--cap-hours", "1"]) == 0
    plan = json.loads((pilot / "seeds.json").read_text())
    seeds = plan["tasks"][0]["seeds"]
    assert plan["cost"]["total_hours"] == pytest.approx(150.0 * seeds * 3 / 3600)
    md = (pilot / "seeds.md").read_text()
    assert "| Hopper | 150.0 |" in md and "against a cap of 1 CPU h" in md
    assert ("**over the cap**" in md) == (plan["cost"]["total_hours"] > 1)
