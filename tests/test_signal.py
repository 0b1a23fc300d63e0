"""The signal check of a meta reward (experiments.analysis.signal) on fabricated grids of fixed-D0 cells: the rank
agreement, the separation and effect ratios, the pass rule and the report."""

import gzip
import json
import os
import shutil

import numpy as np
import pytest

from experiments.analysis import signal
from experiments.analysis.cells import ARCHIVE_CYCLES
from experiments.analysis.render import signal as signal_report
from tests.helpers import fabricate_run


def _cell(root, variant, task, d0, rewards, returns, cycles=4):
    """An archived cell: one final evaluation per seed (its final return) and ``cycles`` cycles per seed, each with
    that seed's meta reward."""
    path = os.path.join(root, variant, "td3", "cells", task, d0)
    fabricate_run(path, "pendulum", "meta", [[r] for r in returns], [300])
    with gzip.open(os.path.join(path, ARCHIVE_CYCLES), "wt") as f:
        for s, r in enumerate(rewards):
            for c in range(cycles):
                f.write(json.dumps({"seed": s, "cycle": c, "meta_reward": r + (c - (cycles - 1) / 2) * 0.01}) + "\n")


def test_rank_agreement_and_the_ratios_on_known_values():
    low, high = np.array([0.0, 1.0]), np.array([10.0, 11.0])
    # The rewards rank the D0s as their returns do, far apart: rho 1 in every resample.
    r = signal.rank_agreement([low, low + 3, low + 6, low + 9], [low, low + 3, low + 6, low + 9], reps=200)
    assert r == {"rho": 1.0, "rho_lo": 1.0, "rho_hi": 1.0}
    # Backwards: -1.
    assert signal.rank_agreement([low, high], [high, low], reps=200)["rho"] == -1.0
    # All returns tied: no ranking, rho 0 (not NaN).
    tied = np.zeros(2)
    assert signal.rank_agreement([low, high], [tied, tied], reps=200) == {"rho": 0.0, "rho_lo": 0.0, "rho_hi": 0.0}
    # Row by row as scipy's, ties included.
    from scipy.stats import spearmanr

    x, y = np.random.default_rng(1).integers(0, 3, (2, 50, 4)).astype(float)
    want = [spearmanr(a, b).statistic if np.ptp(a) and np.ptp(b) else 0.0 for a, b in zip(x, y)]
    np.testing.assert_allclose(signal._rho(x, y), want, atol=1e-9)
    # Gap of the means over the pooled std: means 0.5 and 10.5, both variances 0.5.
    assert np.isclose(signal._gap_ratio([low, high]), 10.0 / np.sqrt(0.5))
    assert signal._gap_ratio([low, low]) == 0.0


def test_the_pass_rule_and_the_report(tmp_path):
    rng = np.random.default_rng(0)
    noise = lambda: rng.normal(0, 0.1, 5)
    returns = {"control-uniform": 300 + 10 * noise(), "control-fixed": 200 + 10 * noise(),
               "control-pink": 100 + 10 * noise(), "control-noiseless": 0 + 10 * noise()}
    # "good" rewards rank the D0s as their returns do, far apart; "backwards" the other way round; "flat" does not
    # separate them. On task "tied" the D0s' returns do not differ: nothing to rank.
    rank = {"control-uniform": 3, "control-fixed": 2, "control-pink": 1, "control-noiseless": 0}
    for task in ("a", "b", "c", "tied"):
        for d0, ret in returns.items():
            ret = ret if task != "tied" else np.array([50.0, 51.0, 52.0, 53.0, 54.0])
            _cell(tmp_path, "good", task, d0, rank[d0] + noise(), ret)
            _cell(tmp_path, "backwards", task, d0, -rank[d0] + noise(), ret)
            _cell(tmp_path, "flat", task, d0, 5 * noise(), ret)
    result = signal.check(str(tmp_path), ["good", "backwards", "flat"], ["a", "b", "c", "tied"], reps=300)
    by = {v["variant"]: v for v in result["variants"]}
    assert [r["outcome"] for r in by["good"]["tasks"]] == ["passed"] * 3 + ["no effect to rank"]
    assert by["good"]["passed"] == 3 and by["good"]["outcome"] == "goes on"
    a = by["good"]["tasks"][0]
    assert a["rho"] == 1.0 and a["rho_lo"] == 1.0 and a["separation"] > 1 and a["effect_p"] < 0.01
    assert by["good"]["tasks"][3]["effect_p"] > 0.05
    assert signal.effect_p([np.zeros(3), np.zeros(3)]) == 1.0  # every return the same (a task at its floor)
    assert a["cells"]["control-fixed"]["seeds"] == 5 and len(a["cells"]["control-fixed"]["rewards"]) == 5
    # each seed's mean over its cycles (the fabricated cycles spread symmetrically around the seed's reward)
    assert np.isclose(a["cells"]["control-fixed"]["reward_mean"], np.mean(a["cells"]["control-fixed"]["rewards"]))
    assert by["backwards"]["tasks"][0]["rho"] == -1.0 and by["backwards"]["outcome"] == "stops"
    assert all(r["rho_lo"] <= 0 < r["rho_hi"] for r in by["flat"]["tasks"][:3]) and by["flat"]["outcome"] == "stops"

    assert signal_report.main(["--results-dir", str(tmp_path), "--variants", "good,backwards,flat",
                               "--tasks", "a,b,c,tied", "--reps", "300"]) == 0
    md = (tmp_path / "signal.md").read_text()
    assert "| good | 3 of 4 | goes on |" in md and "| backwards | 0 of 4 | stops |" in md
    assert "| good | tied | " in md and "no effect to rank" in md
    assert json.loads((tmp_path / "signal.json").read_text())["pass_rule"] == signal.PASS_RULE

    # A missing cell: its task is not judged, and the variant waits while it could still pass.
    shutil.rmtree(tmp_path / "good" / "td3" / "cells" / "a" / "control-pink")
    partial = signal.check(str(tmp_path), ["good"], ["a", "b", "c"], reps=100)["variants"][0]
    assert partial["tasks"][0]["outcome"] == "not judged: control-pink not run" and partial["outcome"] == "pending"


@pytest.mark.parametrize("argv, why", [
    (["--variants", "nope", "--tasks", "a"], "no grid folder"),
    (["--variants", "", "--tasks", "a"], "must name at least one"),
])
def test_bad_options_are_refused_in_one_line(tmp_path, capsys, argv, why):
    assert signal_report.main(["--results-dir", str(tmp_path), *argv]) == 2
    err = capsys.readouterr().err
    assert why in err and err.count("\n") == 1
