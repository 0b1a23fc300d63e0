"""The learned-exploration diagnostics (experiments.analysis.learned) on a fabricated archive, and the archive of a
learned variant's per-cycle metrics (experiments.analysis.cells.archive_cell)."""

import gzip
import json
import math
import os
import shutil

import numpy as np
import pytest

from experiments.analysis import cells, learned
from experiments.analysis.render import learned as learned_report
from experiments.grid.methods import LEARNED_METHODS


def _cycles(seeds):
    """Rows of cycles.jsonl: {seed: [(arm scale, meta reward, sd paired, sd unpaired, distance[, the teacher
    mean's distance]), ...]}."""
    return [{"seed": s, "cycle": c, "meta_reward": r, "teacher_log_std": math.log(scale), "r_hat_pi": 0.0,
             "meta_reward_sd_paired": p, "meta_reward_sd_unpaired": u, "teacher_student_distance": d,
             **({"teacher_mean_distance": m[0]} if m else {})}
            for s, rows in seeds.items() for c, (scale, r, p, u, d, *m) in enumerate(rows)]


def _run(path, config, rows):
    os.makedirs(path)
    with open(os.path.join(path, "config.json"), "w") as f:
        json.dump({"config": {"run": {"total_steps": 300}, **config}, "run_args": {}}, f)
    with open(os.path.join(path, "summary.json"), "w") as f:
        f.write("{}\n")
    with open(os.path.join(path, "metrics.jsonl"), "w") as f:
        f.write(json.dumps({"seed": 0, "chunk": 0, "env_steps": 300, "eval_return": 1.0}) + "\n")
    with open(os.path.join(path, "cycles.jsonl"), "w") as f:
        f.writelines(json.dumps(r) + "\n" for r in rows)


def test_the_diagnostics_of_a_fabricated_bandit_cell(tmp_path):
    # 120 cycles per seed; the last 100 are read. Seed 0 favours 0.4 (80 of 100), seed 1 splits 50/50 (not over
    # half), seed 2 only 0.1; the first 20 cycles (ignored) all use 0.1 with a huge meta reward.
    early = [(0.1, 1e6, 9.0, 9.0, 9.0)] * 20
    seeds = {0: early + [(0.4, 2.0, 1.0, 4.0, 0.2)] * 80 + [(0.1, 2.0, 1.0, 4.0, 0.2)] * 20,
             1: early + [(0.4, -2.0, 1.0, 4.0, 0.4)] * 50 + [(0.1, -2.0, 7.0, 4.0, 0.4)] * 50,
             2: early + [(0.1, 2.0, None, 4.0, 0.6)] * 100}      # a NaN is written as null (runfiles.json_number)
    run = tmp_path / "runs" / "learned-bandit"
    _run(str(run), {"meta": {"teacher": "bandit"}, "bandit": {"scales": [0.1, 0.4]}}, _cycles(seeds))
    archive = tmp_path / "res" / "td3" / "cells" / "hopper" / "learned-bandit"
    assert cells.archive_cell(str(run), str(archive), "learned-bandit")
    first = (archive / cells.ARCHIVE_CYCLES).read_bytes()
    assert cells.archive_cell(str(run), str(archive), "learned-bandit")       # re-archived: the same bytes
    assert (archive / cells.ARCHIVE_CYCLES).read_bytes() == first
    with gzip.open(archive / cells.ARCHIVE_CYCLES, "rt") as f:
        assert len(f.readlines()) == 360

    d = learned.cell_diagnostics(str(archive))
    assert d["seeds"] == 3 and d["cycles_per_seed"] == 100
    # RMS over the 200 finite values (seed 2's nulls dropped): 150 ones and 50 sevens -> sqrt((150 + 50 * 49) / 200)
    assert np.isclose(d["sd_paired_rms"], np.sqrt(13.0)) and d["sd_unpaired_rms"] == 4.0
    assert np.isclose(d["sd_ratio"], np.sqrt(13.0) / 4.0)
    rewards = np.array([2.0] * 100 + [-2.0] * 100 + [2.0] * 100)
    assert np.isclose(d["meta_reward_mean"], rewards.mean()) and np.isclose(d["meta_reward_std"], rewards.std(ddof=1))
    assert np.isclose(d["meta_reward_snr"], abs(rewards.mean()) / rewards.std(ddof=1))
    assert np.isclose(d["meta_reward_seed_std"], np.std([2.0, -2.0, 2.0], ddof=1))    # of the seeds' means
    assert np.isclose(d["distance_mean"], 0.4) and np.isclose(d["distance_std"], 0.2)
    assert d["mean_distance_mean"] is None     # a cell made before the teacher mean's distance was recorded
    b = d["bandit"]
    assert [f["scale"] for f in b["favourites"]][::2] == [0.4, 0.1]   # seed 1's tie goes to either
    assert [f["share"] for f in b["favourites"]] == [0.8, 0.5, 1.0]
    assert b["seeds_over_half"] == 2

    # The report: every learned method of the student on the task, the missing ones said as such.
    out = tmp_path / "res"
    assert learned_report.main(["--results-dir", str(out), "--tasks", "hopper"]) == 0
    md = (out / "diagnostics.md").read_text()
    row = next(line for line in md.splitlines() if "| bandit over noise scales |" in line)
    assert "| 3 | 3.606 | 4.000 | 0.90 |" in row and "| 2 of 3 |" in row
    rows = [line for line in md.splitlines() if line.startswith("| TD3 ")]
    assert len(rows) == len(LEARNED_METHODS) and all(line.count("|") == 15 for line in rows)
    assert "| 0.40 ± 0.20 | – |" in row
    assert sum("| not run |" in line for line in rows) == len(LEARNED_METHODS) - 1
    assert json.loads((out / "diagnostics.json").read_text())["cells"][2]["bandit"]["seeds_over_half"] == 2


def test_only_the_learned_methods_keep_their_cycles(tmp_path):
    run = tmp_path / "run"
    _run(str(run), {"meta": {"teacher": "independent"}}, _cycles({0: [(0.5, 1.0, 1.0, 1.0, 1.0)]}))
    assert cells.archive_cell(str(run), str(tmp_path / "a"), "meta-independent")
    assert not (tmp_path / "a" / cells.ARCHIVE_CYCLES).exists()
    assert learned.cell_diagnostics(str(tmp_path / "a")) == {"state": "no per-cycle metrics archived"}
    assert learned.cell_diagnostics(str(tmp_path / "none")) == {"state": "not run"}


def test_the_hypotheses_predictions_on_a_fabricated_screen(tmp_path):
    """The predictions of results/learned/README.md checked on a fabricated Hopper screen: the comparisons of final
    returns in one Holm family (met / refuted / inconclusive / not run), the diagnostics' thresholds, and the
    variants against every control in a family of their own."""
    from experiments.analysis import stats
    from tests.helpers import fabricate_run

    rng = np.random.default_rng(3)
    steps = np.arange(1, 11) * 300
    means = {"meta-tuned": 500.0, "learned-residual": 501.0, "control-fixed": 300.0, "learned-bandit": 250.0,
             "learned-paired": 400.0, "control-uniform": 100.0}        # control-frozen, control-noiseless: not run
    finals = {}
    cells_dir = tmp_path / "res" / "td3" / "cells" / "hopper"
    for m, mean in means.items():
        values = rng.normal(mean, 5.0, (8, 10))
        fabricate_run(str(cells_dir / m), "hopper", m, values, steps)
        finals[m] = stats.final_returns(values)
    # Per-cycle metrics for two variants: the residual teacher's D0 at distance 0.2 (at most 0.3; its mean at 0.05
    # and 0.15 on the two seeds), the paired reward's spread ratio 0.8 (above 0.5).
    # The bandit's cell has cycles but a config without scales: its arm shares are not measured.
    for m, row, row1 in (("learned-residual", (0.1, 1.0, 1.0, 2.0, 0.2, 0.05), (0.1, 1.0, 1.0, 2.0, 0.2, 0.15)),
                         ("learned-paired", (0.1, 1.0, 0.8, 1.0, 0.9), None),
                         ("learned-bandit", (0.1, 1.0, 1.0, 1.0, 0.1), None)):
        with gzip.open(cells_dir / m / cells.ARCHIVE_CYCLES, "wt") as f:
            f.writelines(json.dumps(r) + "\n" for r in _cycles({0: [row] * 5, 1: [row1 or row] * 5}))
    anchors = tmp_path / "anchors.json"
    anchors.write_text(json.dumps({"tasks": {"hopper": {"random_return": 0.0, "reference_return": 1000.0}}}))
    argv = ["--results-dir", str(tmp_path / "res"), "--tasks", "hopper", "--anchors", str(anchors)]
    figure = tmp_path / "res" / "meta_reward.png"
    assert learned_report.main(argv + ["--no-plot"]) == 0
    assert not figure.exists() and "meta_reward.png" not in (tmp_path / "res" / "diagnostics.md").read_text()
    assert learned_report.main(argv) == 0  # the three cells with per-cycle metrics drawn in one panel
    assert figure.stat().st_size > 10_000
    assert "![meta reward per cycle](meta_reward.png)" in (tmp_path / "res" / "diagnostics.md").read_text()
    pred = json.loads((tmp_path / "res" / "diagnostics.json").read_text())["predictions"]["td3"]

    got = {(r["a"], r["b"]): r for r in pred["comparisons"]}
    assert [r["hypothesis"] for r in pred["comparisons"]] == ["H1", "H1", "H2", "H3"]
    # One family over the three comparisons made (H3's reference was not run), Holm-corrected.
    made = [("learned-residual", "meta-tuned"), ("learned-residual", "control-fixed"),
            ("learned-bandit", "control-fixed")]
    holm = stats.holm([stats.welch_test(finals[a], finals[b])[1] for a, b in made])
    assert [got[k]["p_holm"] for k in made] == pytest.approx(list(holm))
    assert got[made[0]]["verdict"] == "equivalent" and got[made[0]]["outcome"] == "met"  # within ±50
    assert got[made[1]]["verdict"] == "better" and got[made[1]]["outcome"] == "met"
    assert got[made[2]]["verdict"] == "worse" and got[made[2]]["outcome"] == "refuted"    # 'beats' refuted
    assert got[("learned-paired", "control-frozen")]["outcome"] == "not run: control-frozen"
    assert learned.outcome("beats", "inconclusive") == "inconclusive"
    assert learned.outcome("beats", "equivalent") == "refuted" and learned.outcome("not worse", "better") == "met"

    diag = {r["hypothesis"]: r for r in pred["diagnostics"]}
    assert diag["H1"]["outcome"] == "met" and diag["H1"]["value"] == pytest.approx(0.2)
    residual = next(c for c in json.loads((tmp_path / "res" / "diagnostics.json").read_text())["cells"]
                    if c["method"] == "learned-residual")
    assert residual["mean_distance_mean"] == pytest.approx(0.1) and residual["mean_distance_std"] == pytest.approx(
        np.std([0.05, 0.15], ddof=1))
    assert diag["H3"]["outcome"] == "not met" and diag["H3"]["value"] == pytest.approx(0.8)
    assert diag["H2"]["outcome"] == "not measured" and diag["H2"]["value"] is None
    # SAC has no tuned teacher: H1's comparison with it is left out of SAC's family.
    sac = learned.predictions(str(tmp_path / "res"), "sac", ["hopper"], [], None)["comparisons"]
    assert [(r["a"], r["b"]) for r in sac] == [(a, b) for _, a, b, _ in learned.COMPARISONS if b != "meta-tuned"]

    # H4: 3 variants x 5 controls less the 3 pairs judged above; compared where both finished (the 3 variants
    # against uniform D0, the paired-reward teacher against fixed noise).
    done = [r for r in pred["controls"] if r["state"] == "compared"]
    assert len(pred["controls"]) == 12 and len(done) == 4
    assert ("learned-residual", "control-fixed") not in {(r["a"], r["b"]) for r in pred["controls"]}
    assert stats.holm([stats.welch_test(finals[r["a"]], finals[r["b"]])[1] for r in done]) == \
        pytest.approx([r["p_holm"] for r in done])
    md = (tmp_path / "res" / "diagnostics.md").read_text()
    assert "| H2 | bandit over noise scales beats control: D0 with noise 0.1 | Hopper |" in md
    assert "| refuted |" in md and "| not run: control-frozen |" in md and "(H4): a family of its own" in md
    assert learned_report.main(["--results-dir", str(tmp_path / "res"), "--anchors", str(tmp_path / "none.json")]) == 2


def test_the_judgements_goal_from_a_fabricated_benchmark(tmp_path, capsys):
    """--goal on a fabricated judgement (TD3, baseline chosen in advance: parameter noise): a variant far above it
    on every task meets the goal; one far above it on two tasks of three (P's interval above 0.5) but worse on the
    third does not, nor does one no different from it (never worse, P's interval around 0.5); with a cell not run
    the goal is pending and says why; the grid's plan leaves the screen's controls out of the diagnostics."""
    from experiments.analysis import benchmark as artefacts
    from experiments.analysis.render import benchmark as bench_report
    from experiments.grid import methods as grid
    from tests.helpers import fabricate_run

    rng = np.random.default_rng(5)
    steps = np.arange(1, 11) * 300
    runs, res = tmp_path / "runs", tmp_path / "res"
    tasks = {"hopper": (0.0, 1000.0), "reacher": (-40.0, -4.0), "pendulum": (-1200.0, -150.0)}  # anchors
    # Final returns as a fraction of each task's range: the baseline at 0.4, the paired teacher at 0.8 everywhere,
    # the residual teacher at 0.8 on Hopper and Pendulum and 0.1 on Reacher, the bandit at 0.4.
    level = {"td3-paramnoise": {}, "learned-paired": {}, "learned-residual": {"hopper": 0.8, "pendulum": 0.8,
                                                                              "reacher": 0.1},
             "learned-bandit": {}}
    for task, (lo, hi) in tasks.items():
        for m, where in level.items():
            frac = where.get(task, 0.8 if m == "learned-paired" else 0.4)
            values = lo + (hi - lo) * rng.normal(frac, 0.01, (8, 10))
            fabricate_run(str(runs / "td3" / "paper" / grid.task_folder(task) / m), task, m, values, steps)
    anchors = tmp_path / "anchors.json"
    anchors.write_text(json.dumps({"tasks": {t: {"random_return": lo, "reference_return": hi}
                                             for t, (lo, hi) in tasks.items()}}))
    entries = artefacts.entries_for(["td3"], ["learned-paired", "learned-residual", "learned-bandit"],
                                    {"td3": "td3-paramnoise"})
    plan = {"name": "j", "students": ["td3"], "seeds": 8, "seed": 2000, "steps": 3000}
    argv = ["--results-dir", str(res), "--anchors", str(anchors), "--goal"]
    res.mkdir()
    assert learned_report.main(argv) == 2 and "--artefacts-only" in capsys.readouterr().err   # no artefacts built yet
    bench_report.build(str(runs), str(res), entries, list(tasks), anchors_path=str(anchors), plan=plan)
    assert learned_report.main(argv + ["--tasks", "pendulum,hopper,reacher"]) == 0   # the grid's tasks, in any order
    out = capsys.readouterr().out
    report = json.loads((res / "diagnostics.json").read_text())
    g = report["goal"]["td3"]
    assert g["baseline"] == "td3-paramnoise"
    rows = {r["method"]: r for r in g["variants"]}
    assert set(rows) == {"learned-paired", "learned-residual", "learned-bandit"}
    agg = {(p["x"], p["y"]): p for p in json.loads((res / "aggregate.json").read_text())["improvement"]}
    paired = agg[("td3/learned-paired", "td3/td3-paramnoise")]
    assert rows["learned-paired"]["p"] == paired["point"] and rows["learned-paired"]["lo"] == paired["lo"] > 0.5
    assert rows["learned-paired"]["outcome"] == "met" and rows["learned-paired"]["better"] == list(tasks)
    assert (f"goal: TD3 Meta (paired reward) against TD3 (param noise): P = {paired['point']:.2f} "
            f"[{paired['lo']:.2f}, {paired['hi']:.2f}], worse on 0 task(s): met") in out.splitlines()
    residual = agg[("td3/learned-residual", "td3/td3-paramnoise")]
    assert rows["learned-residual"]["lo"] == residual["lo"] > 0.5
    assert rows["learned-residual"]["per_task"] == {"hopper": 1.0, "reacher": 0.0, "pendulum": 1.0}
    assert rows["learned-residual"]["worse"] == ["reacher"] and rows["learned-residual"]["outcome"] == "not met"
    bandit = rows["learned-bandit"]
    assert bandit["worse"] == [] and bandit["lo"] < 0.5 < bandit["hi"] and bandit["outcome"] == "not met"
    # The plan holds no control: none is listed as not run, and no comparison names one.
    assert {c["method"] for c in report["cells"]} == {"learned-paired", "learned-residual", "learned-bandit"}
    assert report["predictions"]["td3"]["comparisons"] == [] and report["predictions"]["td3"]["controls"] == []
    md = (res / "diagnostics.md").read_text()
    assert "## The judgement's goal" in md and "| TD3 | Meta (paired reward) | TD3 (param noise) | " in md
    assert "control:" not in md

    # A planned cell not run: pending, with the reason, whatever the others say.
    shutil.rmtree(res / "td3" / "cells" / "reacher" / "learned-bandit")
    shutil.rmtree(runs / "td3" / "paper" / "reacher" / "learned-bandit")
    bench_report.build(str(runs), str(res), entries, list(tasks), anchors_path=str(anchors), plan=plan)
    assert learned_report.main(argv) == 0
    rows = {r["method"]: r for r in json.loads((res / "diagnostics.json").read_text())["goal"]["td3"]["variants"]}
    assert rows["learned-paired"]["outcome"].startswith(
        "pending (1 of the student's 12 planned cells not finished: reacher/learned-bandit not run")
    # Bad input: a part of the grid's tasks, a student it never planned, a folder without the benchmark's manifest.
    assert learned_report.main(argv + ["--tasks", "hopper"]) == 2 and "not a part of them" in capsys.readouterr().err
    assert learned_report.main(argv + ["--students", "sac"]) == 2 and "sac not in the grid's plan" in capsys.readouterr().err
    (res / "manifest.json").unlink()
    assert learned_report.main(argv) == 2 and "needs the benchmark's manifest.json" in capsys.readouterr().err
