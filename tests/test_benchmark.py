"""experiments.benchmark: bad input, the plan (cells, seeds, folders, each cell's command) with the skip of finished
cells, the resume of a checkpointed one and the calibrated estimate, a tiny benchmark run end to end (run, skip,
resume plan), and the artefacts built from a fabricated benchmark (per-task tables with corrected verdicts, the
aggregate, the sample-efficiency curves, the cost, cells not run shown as not run)."""

import csv
import json
import os

import numpy as np
import pytest

from experiments import benchmark
from experiments.analysis import benchmark as artefacts
from experiments.analysis.render import benchmark as bench_report
from experiments.grid import estimate
from experiments.analysis import stats
from experiments.grid import methods as grid
from experiments.training import grid_cells
from tests.helpers import fabricate_run

# Tiny cells (16-16 networks, 300-step chunks, 2 evaluation episodes) on a fixed replay capacity.
TINY = ["--set", "run.eval_every=300", "--set", "ddpg.hidden=16,16", "--set", "run.eval_episodes=2",
        "--set", "ddpg.batch_size=16", "--set", "run.buffer_size=900"]


def test_bad_input_is_one_error_line_before_anything_runs(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for argv, said in ((["--tasks", "cartpole"], "unknown task 'cartpole'"),
                       (["--students", "ddpg"], "unknown student 'ddpg'; valid: td3, sac"),
                       (["--students", "td3", "--strategies", "sac-pink"], "unknown strategy 'sac-pink'"),
                       (["--seeds", "0"], "--seeds must be positive"),
                       (["--name", "a/b"], "--name 'a/b'"),
                       (["--tasks", "hopper,hopper"], "lists a task twice"),
                       (["--tasks", "pendulum", "--set", "ddpg.nope=1"],
                        "td3/pendulum/td3-normal: unknown config field"),
                       (["--tasks", "pendulum", "--steps", "1000"],
                        "td3/pendulum/meta-independent: run.total_steps=1000 is not a multiple of the 300"),
                       (["--tasks", "gym:InvertedPendulum-v5", "--physics", "mjx", "--students", "sac"],
                        "runs on MuJoCo's C engine only"),
                       (["--baseline", "td3"], "--baseline expects STUDENT=STRATEGY, got 'td3'"),
                       (["--baseline", "td3=sac-pink"], "baseline td3=sac-pink: 'sac-pink' is not a strategy of td3"),
                       (["--students", "td3", "--baseline", "sac=sac-own"], "'sac' is not one of the planned students"),
                       (["--baseline", "td3=td3-pink,td3=td3-ou"], "names student 'td3' twice"),
                       (["--task-steps", "pendulum"], "--task-steps expects TASK=N, got 'pendulum'"),
                       (["--task-seeds", "hopper=0"], "--task-seeds hopper=0: a positive whole number is needed"),
                       (["--tasks", "pendulum", "--task-steps", "hopper=9000"],
                        "--task-steps names 'hopper', which is not one of --tasks (pendulum)"),
                       (["--task-seeds", "hopper=3,hopper=4"], "--task-seeds names 'hopper' twice"),
                       (["--task-set", "hopper=run.eval_every=1"], "--task-set expects TASK:GROUP.FIELD=VALUE"),
                       (["--tasks", "pendulum", "--task-set", "pendulum:ddpg.nope=1"],
                        "td3/pendulum/td3-normal: unknown config field")):
        assert benchmark.main(argv + ["--dry-run", "--no-calibrate"]) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("error: ") and said in err[0], (argv, err)
    assert not os.listdir(tmp_path)


def test_the_default_plan_and_a_gym_task(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert benchmark.main(["--dry-run", "--no-calibrate"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("exploration benchmark 'exploration': 6 tasks x 10 entries (TD3: 7, SAC: 3) = 60 cells "
                             "of 10 seeds, 300,000 env steps per seed, mujoco physics, base seed 1000")
    cells = [line for line in out if line.startswith("[")]
    assert len(cells) == 60 and all(": running: python -m experiments.run" in c for c in cells)
    assert out[-2:] == ["plan: 60 new", "estimated: not calibrated; 60 cells with work left"]
    line = lambda tag: next(c for c in cells if f"] {tag}: " in c)
    hopper = line("td3/hopper/meta-tuned")
    assert "--method=meta --teacher=independent --preset=tuned --seeds=10 --seed=1000" in hopper
    assert "--physics=mujoco --student=td3 --steps=300000" in hopper
    assert hopper.endswith("--out runs/benchmark-exploration/td3/paper/hopper/meta-tuned")
    assert "--preset=paper" in line("td3/hopper/meta-independent") and "--noise=ou --set noise.stddev=0.1" in \
        line("td3/hopper/td3-ou")
    sac = line("sac/pendulum/sac-meta")
    assert "--student=sac" in sac and "--physics" not in sac and "/sac/paper/pendulum/sac-meta" in sac
    assert not (tmp_path / "runs").exists()

    # Any gymnasium MuJoCo task, in a folder of its own name.
    assert benchmark.main(["--tasks", "gym:InvertedPendulum-v5", "--students", "sac", "--strategies", "sac-own",
                           "--dry-run", "--no-calibrate"]) == 0
    cell = next(c for c in capsys.readouterr().out.splitlines() if c.startswith("[1/1]"))
    assert "--env=gym:InvertedPendulum-v5" in cell and cell.endswith("sac/paper/gym-InvertedPendulum-v5/sac-own")
    assert grid.task_folder("gym:Ant-v5(ctrl_cost_weight=0.1)") == "gym-Ant-v5-ctrl_cost_weight=0.1"
    assert grid.task_name("gym:Walker2d-v5") == "Walker2d-v5" and grid.task_name("hopper") == "Hopper"


def test_a_task_can_have_its_own_budget_seeds_and_overrides(tmp_path, capsys, monkeypatch):
    """--task-steps, --task-seeds and --task-set (the hard tasks' benchmark: budgets as the literature uses them,
    seeds by power, evaluations often enough): the task's cells get them, the others keep --steps, --seeds and
    --set; the banner and the manifest's plan say so; TD3 with uniformly random actions is an entry when named."""
    monkeypatch.chdir(tmp_path)
    argv = ["--tasks", "pendulum,dmc:cartpole-swingup_sparse", "--students", "td3", "--strategies", "td3-random",
            "--seeds", "3", "--steps", "9000", "--task-steps", "dmc:cartpole-swingup_sparse=18000",
            "--task-seeds", "dmc:cartpole-swingup_sparse=5", "--task-set", "dmc:cartpole-swingup_sparse:run.eval_every=3000"]
    a = benchmark.build_parser().parse_args(argv)
    tasks, chosen, cells = benchmark.plan(a)      # every cell's config validated
    assert [e.method for e in chosen] == ["td3-normal", "td3-random"]
    by = {(c.task, c.name): c.spec for c in cells}
    for method in ("td3-normal", "td3-random"):
        pend, cart = by[("pendulum", method)], by[("dmc:cartpole-swingup_sparse", method)]
        assert (pend.steps, pend.seeds, pend.overrides) == (9000, 3, ())
        assert (cart.steps, cart.seeds, cart.overrides) == (18000, 5, ("run.eval_every=3000",))
        assert (cart.config().run.eval_every, cart.config().num_chunks) == (3000, 6)
    assert by[("pendulum", "td3-random")].config().run.method == "random"
    assert benchmark.main(argv + ["--dry-run", "--no-calibrate"]) == 0
    banner = capsys.readouterr().out.splitlines()[0]
    assert banner.startswith("exploration benchmark 'exploration': 2 tasks x 2 entries (TD3: 2) = 4 cells of 3 seeds, "
                             "9,000 env steps per seed, mujoco physics, base seed 1000; dmc:cartpole-swingup_sparse: "
                             "5 seeds, 18,000 steps, run.eval_every=3000; cells in "), banner

    # --preset modern: every cell but a method's own preset (the tuned teacher) under it, in <student>/modern/.
    a = benchmark.build_parser().parse_args(["--tasks", "pendulum", "--students", "td3", "--strategies",
                                             "td3-pink,meta-tuned", "--preset", "modern", "--steps", "36000"])
    _, _, cells = benchmark.plan(a)
    assert {c.name: c.spec.config().preset for c in cells} == {"td3-normal": "modern", "td3-pink": "modern",
                                                               "meta-tuned": "tuned"}
    assert benchmark.main(["--tasks", "pendulum", "--students", "td3", "--preset", "modern", "--steps", "36000",
                           "--dry-run", "--no-calibrate", "--strategies", "td3-pink"]) == 0
    out = capsys.readouterr().out
    assert ", modern preset; cells in runs/benchmark-exploration/<student>/modern/" in out
    assert "runs/benchmark-exploration/td3/modern/pendulum/td3-pink" in out and "--preset=modern" in out


def test_the_learned_variants_are_entries_only_when_named_and_share_one_cycle_on_every_task(tmp_path, monkeypatch):
    """results/learned/README.md: the variants and controls run under the tuned preset in one 750-step cycle (a third
    of it D0, the paired baseline) that divides the budget and the evaluation interval on all six tasks."""
    monkeypatch.chdir(tmp_path)
    assert all(e.method not in grid.LEARNED_METHODS for e in artefacts.entries_for(["td3", "sac"]))
    a = benchmark.build_parser().parse_args(["--students", "td3,sac", "--strategies", ",".join(grid.LEARNED_METHODS)])
    tasks, chosen, cells = benchmark.plan(a)      # every cell's config validated
    assert [e.method for e in chosen] == ["td3-normal", *grid.LEARNED_METHODS, "sac-own", *grid.LEARNED_METHODS]
    for cell in cells:
        if cell.name in grid.LEARNED_METHODS:
            cfg = cell.spec.config()
            assert (cfg.preset, cfg.steps_per_cycle, cfg.meta.explore_steps, cfg.meta.baseline) == \
                ("tuned", 750, 250, "paired"), cell.tag
            assert (cfg.run.train_steps, cfg.meta.lookahead_steps, cfg.meta.teacher_steps) == (375, 125, 1), cell.tag
    assert len(cells) == 6 * 2 * (1 + len(grid.LEARNED_METHODS)) and not (tmp_path / "runs").exists()


def test_the_plan_skips_done_cells_resumes_checkpointed_ones_and_estimates_the_rest(tmp_path, capsys):
    runs, results = tmp_path / "runs", tmp_path / "res"
    argv = ["--tasks", "pendulum,reacher", "--students", "td3,sac", "--strategies", "td3-normal,td3-pink,sac-own",
            "--seeds", "2", "--steps", "900", "--runs-dir", str(runs), "--results-dir", str(results), *TINY]
    steps = np.array([300, 600, 900])
    fabricate_run(runs / "td3" / "paper" / "pendulum" / "td3-normal", "pendulum", "td3-normal", np.zeros((2, 3)), steps,
                  seed=1000)
    killed = runs / "td3" / "paper" / "pendulum" / "td3-pink"  # killed after its first checkpoint (chunk 1)
    fabricate_run(killed, "pendulum", "td3-pink", np.zeros((2, 1)), steps[:1], complete=False)
    (killed / "checkpoints" / "1").mkdir(parents=True)
    empty = runs / "td3" / "paper" / "reacher" / "td3-pink"  # killed before its first checkpoint
    empty.mkdir(parents=True)
    (empty / "config.json").write_text("{}")
    # Finished in an earlier clone: only the archive holds it.
    fabricate_run(results / "sac" / "cells" / "reacher" / "sac-own", "reacher", "sac-own", np.zeros((2, 3)), steps,
                  seed=1000)
    assert benchmark.main(argv + ["--dry-run", "--no-calibrate"]) == 0
    out = capsys.readouterr().out
    assert "td3/pendulum/td3-normal: done, skipped: final return 0.0" in out
    assert "td3/pendulum/td3-pink: resuming: python -m experiments.run" in out
    assert f"--resume {killed}" in out
    assert "td3/reacher/td3-pink: restarting (no checkpoint stored)" in out and "--overwrite" in out
    assert "sac/reacher/sac-own: done, skipped" in out and "sac/pendulum/sac-own: running" in out
    assert "plan: 2 done, 2 new, 1 restart, 1 resume" in out

    # The estimate: each entry calibrated on the first task (pendulum), reacher scaled by the student's baseline.
    measured = {("pendulum", "td3-normal"): (10.0, 1e-3), ("pendulum", "td3-pink"): (20.0, 2e-3),
                ("reacher", "td3-normal"): (30.0, 4e-3), ("pendulum", "sac-own"): (5.0, 1e-3)}
    calls = []

    def fake_run(spec, method, chunk_steps):
        calls.append((spec.student, spec.task, method, chunk_steps))
        compile_s, per_step = measured[(spec.task, method)]
        return {"compile_seconds": compile_s, "seconds_per_step": per_step, "cpu_utilisation": 1.5, "seeds": 2}

    a = benchmark.build_parser().parse_args(argv + ["--dry-run", "--calibration-steps", "600"])
    tasks, chosen, cells = benchmark.plan(a)
    todo = [(c, p) for c, p in ((c, grid_cells.plan_cell(c)) for c in cells) if p["argv"]]
    estimates, _, failures = estimate.calibrate(a, tasks, todo, run=fake_run)
    assert not failures and sorted(calls) == sorted([("td3", "pendulum", "td3-normal", 600),
                                                     ("td3", "pendulum", "td3-pink", 600),
                                                     ("td3", "reacher", "td3-normal", 600),
                                                     ("sac", "pendulum", "sac-own", 600)])
    assert set(estimates) == {("td3", "reacher", "td3-normal"), ("td3", "pendulum", "td3-pink"),
                              ("td3", "reacher", "td3-pink"), ("sac", "pendulum", "sac-own")}
    # Resumed after 1 of 3 chunks: 600 steps left. Reacher: pink's pendulum numbers x the baseline's reacher/pendulum.
    assert estimates[("td3", "pendulum", "td3-pink")]["wall_seconds"] == pytest.approx(20 + 600 * 2e-3)
    assert estimates[("td3", "reacher", "td3-pink")]["wall_seconds"] == pytest.approx(20 * 3 + 900 * 2e-3 * 4)
    assert estimates[("td3", "reacher", "td3-pink")]["cpu_seconds"] == pytest.approx(1.5 * (60 + 7.2))
    assert not runs.joinpath("sac").exists()  # nothing ran


@pytest.mark.slow
def test_a_tiny_benchmark_runs_archives_skips_and_plans_the_resume(tmp_path, capsys):
    runs, results = tmp_path / "runs", tmp_path / "res"
    argv = ["--tasks", "pendulum", "--students", "td3", "--strategies", "td3-normal", "--seeds", "2", "--steps", "600",
            "--runs-dir", str(runs), "--results-dir", str(results), "--quiet", "--no-plot", *TINY]
    assert benchmark.main(argv) == 0
    out = capsys.readouterr().out
    assert "benchmark: 1 ran" in out
    cell = runs / "td3" / "paper" / "pendulum" / "td3-normal"
    archived = results / "td3" / "cells" / "pendulum" / "td3-normal"
    record = json.loads((archived / "reproduce.json").read_text())
    assert record["cpu_seconds"] > 0 and record["cpu_seconds_calls"] == 1
    assert "--student=td3" in record["calls"][0]["argv"]
    summary = json.loads((cell / "summary.json").read_text())
    table = json.loads((results / "tasks" / "pendulum.json").read_text())
    assert table["rows"][0]["per_seed"] == pytest.approx(summary["final_return_per_seed"])
    cost = json.loads((results / "cost.json").read_text())
    assert cost["cells"][0]["cpu_seconds"] == record["cpu_seconds"] and cost["cells"][0]["env_steps_per_second"] > 0
    manifest = json.loads((results / "manifest.json").read_text())
    assert manifest["cells"][0]["student"] == "td3" and manifest["not_run"] == []
    assert manifest["benchmark"]["seed"] == 1000 and manifest["benchmark"]["argv"] == argv

    assert benchmark.main(argv) == 0  # done: skipped, the artefacts rebuilt
    assert "benchmark: 1 skipped" in capsys.readouterr().out
    (cell / "summary.json").unlink()  # as if killed after its last checkpoint
    assert benchmark.main(argv + ["--dry-run", "--no-calibrate"]) == 0
    assert ": resuming: python -m experiments.run" in capsys.readouterr().out


def _write_rows(path, extra):
    """Adds fields to every row of a fabricated run's metrics.jsonl."""
    rows = [json.loads(line) for line in (path / "metrics.jsonl").read_text().splitlines()]
    (path / "metrics.jsonl").write_text("".join(json.dumps({**r, **extra(r)}) + "\n" for r in rows))


def test_the_artefacts_of_a_fabricated_benchmark(tmp_path):
    """2 tasks x 2 students (TD3: Gaussian, pink noise, the teacher; SAC: own, pink): per-task tables with
    Holm-corrected verdicts per student, the aggregate over the task where every cell finished, the best fixed
    noise, the curves, the cost, and a cell never run shown as not run."""
    runs, results = tmp_path / "runs", tmp_path / "res"
    rng = np.random.default_rng(0)
    steps = np.arange(1, 11) * 300
    means = {"td3-normal": 400.0, "td3-pink": 800.0, "meta-independent": 300.0, "sac-own": 500.0, "sac-pink": 520.0}
    values = {}
    gym_task = "gym:InvertedPendulum-v5"  # no normalisation anchors
    for task, scale in (("hopper", 1.0), ("reacher", -0.01), (gym_task, 1.0)):
        for student, methods in (("td3", ("td3-normal", "td3-pink", "meta-independent")),
                                 ("sac", ("sac-own", "sac-pink"))):
            for m in methods:
                if (task, m) == ("reacher", "sac-pink"):
                    continue  # never run
                values[(task, m)] = scale * rng.normal(means[m], 30.0, (4, 10)) * np.linspace(0.2, 1.0, 10)
                fabricate_run(runs / student / "paper" / grid.task_folder(task) / m, task, m, values[(task, m)], steps)
    hopper_pink = runs / "td3" / "paper" / "hopper" / "td3-pink"
    _write_rows(hopper_pink, lambda r: {"wall_time": 2.0 * (r["chunk"] + 1), "chunk_seconds": 2.0})
    grid_cells.write_cell_record(str(hopper_pink), ["--a"], 0, 25.0, {"commit": "c", "dirty": False,
                                                                     "machine": {"cpu_count": 2}}, cpu_seconds=40.0)
    anchors = tmp_path / "anchors.json"
    ranges = {"hopper": (0.0, 1000.0), "reacher": (-40.0, -4.0)}
    anchors.write_text(json.dumps({"tasks": {t: {"random_return": lo, "reference_return": hi}
                                             for t, (lo, hi) in ranges.items()}}))
    entries = artefacts.entries_for(["td3", "sac"], ["td3-pink", "meta-independent", "sac-pink"])
    assert [e.key for e in entries] == ["td3/td3-normal", "td3/td3-pink", "td3/meta-independent", "sac/sac-own",
                                        "sac/sac-pink"]  # each student's Gaussian noise always planned
    manifest = bench_report.build(str(runs), str(results), entries, ["hopper", "reacher", gym_task],
                               plan={"name": "t", "students": ["td3", "sac"], "seeds": 4, "seed": 1000, "steps": 3000,
                                     "physics": "mujoco"}, anchors_path=str(anchors))
    assert manifest["not_run"] == [["sac", "reacher", "sac-pink"]]
    for name in ("tasks/hopper.md", "tasks/hopper.json", "tasks/hopper_per_seed.csv", "tasks/reacher.md",
                 "aggregate.md", "aggregate.json", "aggregate_scores.png", "performance_profiles.png",
                 "sample_efficiency.json", "sample_efficiency.png", "cost.md", "cost.json", "README.md"):
        assert name in manifest["files"] and (results / name).exists(), name
    assert (results / "td3" / "cells" / "hopper" / "td3-pink" / "summary.json").exists()  # archived per student

    # Where exploration matters: per task, best - worst entry mean over the seeds' pooled std (all five entries on
    # Hopper, four on Reacher), and over the range where the task has anchors (not the gym: task).
    matters = {r["task"]: r for r in json.loads((results / "exploration_matters.json").read_text())["tasks"]}
    assert sorted(matters) == sorted(["hopper", "reacher", gym_task])
    for task, entries_ in (("hopper", ("td3-normal", "td3-pink", "meta-independent", "sac-own", "sac-pink")),
                           ("reacher", ("td3-normal", "td3-pink", "meta-independent", "sac-own"))):
        finals = {m: stats.final_returns(values[(task, m)]) for m in entries_}
        means = {m: float(np.mean(v)) for m, v in finals.items()}
        pooled = np.sqrt(sum(np.var(v, ddof=1) * (v.size - 1) for v in finals.values())
                         / sum(v.size - 1 for v in finals.values()))
        spread = max(means.values()) - min(means.values())
        r = matters[task]
        assert r["cells"] == len(entries_) and r["spread"] == pytest.approx(spread)
        assert r["figure"] == pytest.approx(spread / pooled)
        assert r["spread_fraction"] == pytest.approx(spread / (ranges[task][1] - ranges[task][0]))
        assert r["best"].endswith("/" + max(means, key=means.get))
    assert matters[gym_task]["spread_fraction"] is None

    # Per task: every cell, the verdicts of one family per student (its strategies against its Gaussian noise on
    # both tasks), Holm-corrected.
    final = lambda t, m: stats.final_returns(values[(t, m)])
    rows_of = lambda task: json.loads((results / "tasks" / f"{task}.json").read_text())["rows"]
    table = {(r["student"], r["method"]): r for r in rows_of("reacher")}
    assert table[("sac", "sac-pink")]["status"] == "not run" and table[("td3", "td3-normal")]["verdict"] is None
    raw = [stats.welch_test(final(t, m), final(t, "td3-normal"))[1] for m in ("td3-pink", "meta-independent")
           for t in ("hopper", "reacher", gym_task)]
    holm = stats.holm(raw)
    assert table[("td3", "td3-pink")]["verdict"]["p_holm"] == pytest.approx(holm[1])
    assert table[("td3", "meta-independent")]["verdict"]["p_holm"] == pytest.approx(holm[4])
    assert table[("td3", "td3-pink")]["verdict"]["margin"] == pytest.approx(0.05 * 36)
    md = (results / "tasks" / "reacher.md").read_text()
    assert "| SAC | SAC (pink noise) | not run | not run |" in md
    assert "| TD3 | TD3 + Meta (independent) |" in md and "TD3: 6 comparisons, SAC: 2 comparisons" in md
    hopper = {(r["student"], r["method"]): r for r in rows_of("hopper")}
    assert hopper[("td3", "td3-pink")]["verdict"]["verdict"] == "better"
    sac_raw = [stats.welch_test(final(t, "sac-pink"), final(t, "sac-own"))[1] for t in ("hopper", gym_task)]
    assert hopper[("sac", "sac-pink")]["verdict"]["p_holm"] == pytest.approx(stats.holm(sac_raw)[0])
    with open(results / "tasks" / "hopper_per_seed.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 5 * 4 and float(rows[4]["final_return"]) == pytest.approx(final("hopper", "td3-pink")[0])

    # The aggregate: over hopper only (reacher has a cell not run), the best fixed noise by IQM.
    rep = json.loads((results / "aggregate.json").read_text())
    assert rep["tasks"] == ["hopper"] and rep["left_out"] == ["Reacher (no finished cell for SAC (pink noise))",
                                                              "InvertedPendulum-v5 (no normalisation anchors)"]
    gym_rows = json.loads((results / "tasks" / "gym-InvertedPendulum-v5.json").read_text())["rows"]
    assert gym_rows[1]["verdict"]["margin"] is None and gym_rows[1]["verdict"]["verdict"] != "equivalent"
    scores = lambda m: stats.normalise(final("hopper", m), *ranges["hopper"])
    assert rep["methods"]["td3/td3-pink"]["IQM"]["point"] == pytest.approx(stats.iqm(scores("td3-pink")))
    assert rep["best_fixed_noise"] == {s: {"entry": f"{s}/{m}", "IQM": pytest.approx(stats.iqm(scores(m)))}
                                       for s, m in (("td3", "td3-pink"), ("sac", "sac-pink"))}
    pairs = {(p["x"], p["y"], p["reference"]): p for p in rep["improvement"]}
    assert set(pairs) == {("td3/td3-pink", "td3/td3-normal", "baseline"),
                          ("td3/meta-independent", "td3/td3-normal", "baseline"),
                          ("sac/sac-pink", "sac/sac-own", "baseline"),
                          ("td3/td3-normal", "td3/td3-pink", "best fixed noise"),
                          ("td3/meta-independent", "td3/td3-pink", "best fixed noise"),
                          ("sac/sac-own", "sac/sac-pink", "best fixed noise")}
    assert pairs[("td3/td3-pink", "td3/td3-normal", "baseline")]["point"] == 1.0
    assert "same seeds" in rep["best_fixed_noise_rule"] and "| Y is |" in (results / "aggregate.md").read_text()

    # Sample efficiency: the IQM of the normalised evaluation returns at each evaluation point.
    curves = json.loads((results / "sample_efficiency.json").read_text())
    assert curves["steps"] == steps.tolist() and curves["tasks"] == ["hopper"]
    pink = curves["entries"]["td3/td3-pink"]
    assert pink["iqm"][3] == pytest.approx(stats.iqm(stats.normalise(values[("hopper", "td3-pink")][:, 3], 0, 1000)))
    assert pink["lo"][3] <= pink["iqm"][3] <= pink["hi"][3]

    # The cost: from the records, never estimated.
    cost = json.loads((results / "cost.json").read_text())
    row = next(c for c in cost["cells"] if (c["task"], c["method"]) == ("hopper", "td3-pink"))
    assert row["cpu_seconds"] == 40.0 and row["wall_seconds"] == 25.0 and row["train_seconds"] == 20.0
    assert row["env_steps_per_second"] == pytest.approx(4 * 3000 / 20.0) and row["compile_seconds"] == 0.5
    # At the paper's budget (Hopper: 990k), projected from the record: compile + the rest scaled by 990k / 3k.
    assert row["paper_budget"] == 990_000 and row["paper_budget_wall_seconds"] == pytest.approx(0.5 + 24.5 * 330)
    assert row["paper_budget_cpu_seconds"] == pytest.approx(40.0 * (0.5 + 24.5 * 330) / 25.0, abs=0.1)
    gym_row = next(c for c in cost["cells"] if c["task"] == gym_task and c["method"] == "td3-pink")
    assert "paper_budget" not in gym_row                       # a gym: task has no paper budget
    assert next(c for c in cost["cells"] if c["method"] == "sac-pink" and c["task"] == "reacher")["status"] == "not run"
    assert cost["totals"]["cpu_seconds"] == 40.0 and cost["totals"]["cells_not_run"] == 1
    readme = (results / "README.md").read_text()
    mean, std = stats.mean_std(final("hopper", "td3-pink"))
    assert "1 not run (sac/reacher/sac-pink)" in readme and "| SAC | SAC (pink noise) |" in readme
    assert f"| TD3 | TD3 (pink noise) | {stats.fmt(mean)} ± {stats.fmt(std)} (better) |" in readme
    # Verdict counts per strategy: its tasks judged against the baseline (SAC's pink noise: reacher not run).
    counts = manifest["verdict_counts"]
    assert set(counts) == {"td3/td3-pink", "td3/meta-independent", "sac/sac-pink"}
    assert sum(counts["td3/td3-pink"].values()) == 3 and sum(counts["sac/sac-pink"].values()) == 2
    said = [r["verdict"]["verdict"] for t in ("hopper", "reacher", gym_task) for r in rows_of(grid.task_folder(t))
            if r["method"] == "td3-pink"]
    assert counts["td3/td3-pink"] == {v: said.count(v) for v in stats.VERDICTS} and counts["td3/td3-pink"]["better"]
    line = next(x for x in readme.splitlines() if x.startswith("| TD3 | TD3 (pink noise) |"))
    assert line.endswith(" | " + " / ".join(str(counts["td3/td3-pink"][v]) for v in stats.VERDICTS) + " |")
    assert "| verdicts (better / worse / equivalent / inconclusive) |" in readme
    assert "`NOTES.md`" not in readme      # a hand-kept file is listed only where it exists
    (results / "NOTES.md").write_text("# how the cells ran\n")
    bench_report.build(str(runs), str(results), entries, ["hopper", "reacher", gym_task], anchors_path=str(anchors),
                    plan={"name": "t", "students": ["td3", "sac"], "seeds": 4, "seed": 1000, "steps": 3000})
    assert "| `NOTES.md` | how the cells ran, kept by hand" in (results / "README.md").read_text()
    assert (results / "NOTES.md").read_text() == "# how the cells ran\n"
    from experiments.aggregate import repo_path  # the verdicts' definition names the anchors file the build read
    assert f"normalised range (reference − random policy's return, {repo_path(str(anchors))})" in \
        (results / "tasks" / "hopper.md").read_text()

    # A baseline chosen in advance (TD3's pink noise): it is planned, Gaussian noise is not unless named, and the
    # verdicts and P(improvement) of TD3's other strategies are against it.
    chosen = artefacts.entries_for(["td3"], ["meta-independent"], {"td3": "td3-pink"})
    assert [(e.key, e.baseline) for e in chosen] == [("td3/td3-pink", "td3-pink"),
                                                     ("td3/meta-independent", "td3-pink")]
    judged = tmp_path / "judged"
    bench_report.build(str(runs), str(judged), chosen, ["hopper", "reacher"], anchors_path=str(anchors),
                    plan={"name": "j", "students": ["td3"], "seeds": 4, "seed": 1000, "steps": 3000})
    rows = {r["method"]: r for r in json.loads((judged / "tasks" / "hopper.json").read_text())["rows"]}
    assert rows["td3-pink"]["verdict"] is None and rows["meta-independent"]["baseline"] == "td3-pink"
    raw = [stats.welch_test(final(t, "meta-independent"), final(t, "td3-pink"))[1] for t in ("hopper", "reacher")]
    assert rows["meta-independent"]["verdict"]["p_holm"] == pytest.approx(stats.holm(raw)[0])
    assert rows["meta-independent"]["verdict"]["verdict"] == "worse"
    rep = json.loads((judged / "aggregate.json").read_text())
    assert [(p["x"], p["y"], p["reference"]) for p in rep["improvement"]] == [
        ("td3/meta-independent", "td3/td3-pink", "baseline")]   # its best fixed noise is the baseline: not twice
    assert "against its student's baseline (TD3: TD3 (pink noise))" in (judged / "tasks" / "hopper.md").read_text()
    assert "Baselines: TD3 (pink noise)." in (judged / "README.md").read_text()
    assert "| TD3 + Meta (independent) | " in (judged / "README.md").read_text()
    assert "(its baseline is the best) |" in (judged / "README.md").read_text()
    assert json.loads((judged / "manifest.json").read_text())["benchmark"]["baselines"] == {"td3": "td3-pink"}
