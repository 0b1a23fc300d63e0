"""A grid's cell as typed data (``experiments.grid.spec``): its config is the one its command line gives, and a
grid refuses a finished cell stored with other seeds."""

import os

import pytest

from experiments import reproduce
from experiments import run as run_lib
from experiments.grid.methods import METHODS, STUDENT_OF
from experiments.grid.spec import CellSpec, GridRun, GridSpec, method
from experiments.training import args as training_args
from experiments.training import grid_cells
from experiments.training.screen_variants import VARIANTS
from metapg_jax.config import make_config
from tests.helpers import fabricate_run


def parsed_config(spec: CellSpec):
    """The config ``experiments.run`` builds from the spec's command line."""
    parsed = run_lib.build_parser().parse_args(spec.argv() + ["--out", os.devnull])
    return training_args.config_from_run_args(training_args.run_args(parsed))


def test_every_grid_method_gives_the_config_of_its_command_line():
    """For every grid method (each with its student) and every screen variant, on a JAX task and a MuJoCo task,
    with the grid's own overrides and budget: ``CellSpec.config()`` == the config parsed from ``CellSpec.argv()``."""
    for name, m in METHODS.items():
        for task in ("pendulum", "hopper"):
            spec = CellSpec(task, m, student=STUDENT_OF.get(name, "ddpg"), seeds=3, seed=7, physics="mujoco",
                            overrides=("run.eval_episodes=2",))
            cfg = spec.config()
            assert cfg == parsed_config(spec), (name, task)
            assert (cfg.preset, cfg.student, cfg.run.eval_episodes) == (m.preset or "paper", spec.student, 2)
    for name, v in VARIANTS.items():
        for task in ("hopper", "halfcheetah"):
            sets = v.sets(make_config(task, "meta", physics="mujoco"))
            if sets is not None:
                spec = CellSpec(task, v.method.setting(*sets), seeds=2, steps=30_000, physics="mujoco")
                assert spec.config() == parsed_config(spec), (name, task)


def test_a_spec_writes_the_command_line_the_grids_recorded():
    """``reproduce.json``'s argv (what ``experiments.verify`` re-runs) keeps its form."""
    grid = GridRun("runs", "results")
    spec = GridSpec(physics="mujoco", seeds=10, seed=4000, overrides=("run.eval_episodes=2",))
    cell = grid_cells.grid_cell(grid, spec, "hopper", "td3-normal")
    assert grid_cells.cell_argv(cell, "runs/x", "new") == [
        "--env=hopper", "--method=ddpg", "--noise=normal", "--set", "noise.stddev=0.1", "--preset=paper", "--seeds=10",
        "--seed=4000", "--source=gymnasium", "--physics=mujoco", "--set", "run.eval_episodes=2", "--out", "runs/x"]
    tuned = grid_cells.grid_cell(grid, spec, "pendulum", "meta-tuned")
    assert grid_cells.cell_argv(tuned, "runs/y", "extend")[:6] == [
        "--env=pendulum", "--method=meta", "--teacher=independent", "--preset=tuned", "--seeds=10", "--seed=4000"]
    assert "--steps=900000" in grid_cells.cell_argv(tuned, "runs/y", "extend")
    assert method("ddpg", "noise.stddev=0.1", noise="normal") == METHODS["td3-normal"]
    # How the grid runs its cells: only what is not a default is written (a recorded line keeps its form).
    how = GridRun("runs", "results", quiet=True, checkpoint_minutes=10, term_grace=50)
    assert how.run_options() == ["--quiet", "--checkpoint-minutes=10", "--term-grace=50"]
    assert GridRun("runs", "results", term_grace=0).run_options() == ["--term-grace=0"]
    assert GridRun("runs", "results", term_grace=25.0).run_options() == []


def test_a_finished_cell_stored_with_other_seeds_stops_the_grid_before_anything_runs(tmp_path, capsys):
    """Its numbers would otherwise be taken for the requested cell's ("done, skipped")."""
    results = tmp_path / "res"
    fabricate_run(results / "cells" / "pendulum" / "ddpg-normal", "pendulum", "ddpg-normal", [[0.0]] * 8, [9_000],
                  seed=0)
    argv = ["--tasks", "pendulum", "--methods", "ddpg-normal", "--runs-dir", str(tmp_path / "runs"),
            "--results-dir", str(results), "--steps", "9000", "--dry-run"]
    assert reproduce.main(argv + ["--seeds", "8"]) == 0
    assert "done, skipped" in capsys.readouterr().out
    assert reproduce.main(argv + ["--seeds", "10", "--seed", "4000"]) == 2
    err = capsys.readouterr().err
    assert "paper/pendulum/ddpg-normal" in err and "stored with seeds 8 (requested 10), seed 0 (requested 4000)" in err


@pytest.mark.slow
def test_every_study_resolves_every_stored_cell_of_its_grid(capsys, tmp_path):
    """``python -m experiments.grid <study> --dry-run`` for every named study: its settings are options of its kind,
    and every cell of a finished study resolves to its archived copy (nothing would run). ``table2-c`` and
    the modern-preset check of the hard-exploration pilot run over several sittings, and the signal check's grids
    have not finished: their plans only have to parse and validate."""
    from experiments.grid.__main__ import main
    from experiments.grid.studies import studies

    unfinished = {"table2-c", "exploration-hard", "exploration-hard-modern-check", "learned-signal-paired",
                  "learned-signal-counterfactual-d0", "learned-signal-counterfactual-mix"}
    for name, study in studies().items():
        extra = ["--no-calibrate"] if study.kind == "benchmark" else []
        assert main([name, "--dry-run", "--runs-dir", str(tmp_path / "runs"), *extra]) == 0, name
        out = capsys.readouterr().out
        assert "\nplan: " in out, name
        if name not in unfinished:
            assert ": running:" not in out and "estimated: nothing to run" in out, name


def test_a_study_refuses_an_option_that_would_change_it(capsys):
    from experiments.grid.__main__ import main

    assert main(["learned-judgement", "--seed", "5", "--dry-run"]) == 2
    assert "is defined with --seed 2000" in capsys.readouterr().err
    assert main(["table2-td3", "--tasks", "pendulum", "--dry-run"]) == 2
    assert "has no task 'pendulum'" in capsys.readouterr().err
    assert main(["no-such-study"]) == 2 and "unknown study 'no-such-study'" in capsys.readouterr().err
    assert main(["--list"]) == 0 and "table2-c" in capsys.readouterr().out


def test_a_study_narrowed_to_some_tasks_keeps_their_own_settings_and_drops_the_others():
    """``--tasks`` narrows a benchmark study with per-task budgets and overrides: the kept task keeps its own, the
    others' are left out (the benchmark command alone refuses a setting of a task it does not run)."""
    from experiments import benchmark
    from experiments.grid.__main__ import parse_study
    from experiments.grid.studies import studies

    study = studies()["exploration-hard-modern-check"]
    _, a = parse_study(study, ["--tasks", "mountain_car_continuous"])
    assert a.task_steps == ["mountain_car_continuous=50000"]
    assert a.task_set == ["mountain_car_continuous:run.eval_every=1000"]
    per_task = benchmark.task_settings(a, ["mountain_car_continuous"])
    assert per_task["mountain_car_continuous"]["steps"] == 50000
    assert per_task["mountain_car_continuous"]["overrides"][-1] == "run.eval_every=1000"
    _, whole = parse_study(study, [])  # not narrowed: every task's settings
    assert len(whole.task_set) == 2 and whole.task_set[1].startswith("dmc:cartpole-swingup_sparse:")
    with pytest.raises(ValueError, match="--task-set names 'dmc:cartpole-swingup_sparse', which is not one of"):
        benchmark.task_settings(whole, ["mountain_car_continuous"])


def test_a_narrowed_study_runs_its_cells_and_leaves_the_studys_report_alone(tmp_path, capsys):
    """The study's report covers every cell of it: a call narrowed by ``--tasks`` does not rebuild it from part of
    them (``--report-only`` so narrowed is refused), unless ``--results-dir`` names a folder of its own; a task
    outside the study is refused whether the study names its tasks or keeps its kind's."""
    import argparse

    from experiments.grid import engine
    from experiments.grid.__main__ import main, parse_study
    from experiments.grid.studies import studies

    found = studies()
    _, a = parse_study(found["exploration-hard-modern-check"], ["--tasks", "mountain_car_continuous"])
    assert "report is not rebuilt" in a.skip_report
    _, a = parse_study(found["exploration"], ["--tasks", "hopper"])  # the kind's tasks, narrowed
    assert "'exploration'" in a.skip_report
    _, whole = parse_study(found["exploration"], [])
    assert not getattr(whole, "skip_report", None)
    _, elsewhere = parse_study(found["exploration"], ["--tasks", "hopper", "--results-dir", str(tmp_path)])
    assert not getattr(elsewhere, "skip_report", None)
    for argv in (["exploration", "--tasks", "hopper", "--report-only"],
                 ["table2-c", "--tasks", "hopper", "--report-only"]):  # table2-c names its results folder
        assert main(argv) == 2
        assert "--report-only with --tasks would rebuild study" in capsys.readouterr().err
    assert main(["exploration", "--tasks", "gym:Walker2d-v5", "--dry-run"]) == 2
    assert "study 'exploration' has no task 'gym:Walker2d-v5'" in capsys.readouterr().err

    built = []
    plan = engine.GridPlan([], ["hopper"], built.append)
    ns = argparse.Namespace(dry_run=False, launcher="local", skip_report="not rebuilt: narrowed")
    assert engine.run(ns, lambda: plan, report_only=False) == 0 and built == []
    assert "not rebuilt: narrowed" in capsys.readouterr().out
    del ns.skip_report
    assert engine.run(ns, lambda: plan, report_only=False) == 0 and len(built) == 1


def test_reproduce_estimates_its_cells_when_asked(tmp_path, capsys, monkeypatch):
    """``--estimate`` with ``--dry-run``: every method calibrated on the calibration task, the other tasks scaled
    by DDPG's Gaussian noise there (``experiments.grid.estimate``; a fake calibration here)."""
    from experiments.grid import estimate

    calls = []

    def fake_run(spec, name, chunk_steps):
        calls.append((spec.task, name))
        return {"compile_seconds": 10.0, "seconds_per_step": 1e-3 * (2 if spec.task == "reacher" else 1),
                "cpu_utilisation": 1.0, "seeds": spec.seeds}

    monkeypatch.setattr(estimate, "calibration_run", fake_run)
    argv = ["--tasks", "pendulum,reacher", "--methods", "meta-independent,ddpg-normal", "--steps", "6000",
            "--runs-dir", str(tmp_path / "runs"), "--results-dir", str(tmp_path / "res"), "--dry-run"]
    assert reproduce.main(argv) == 0 and not calls  # no estimate unless asked
    capsys.readouterr()
    assert reproduce.main(argv + ["--estimate", "--calibration-task", "pendulum"]) == 0
    out = capsys.readouterr().out
    assert sorted(calls) == [("pendulum", "ddpg-normal"), ("pendulum", "meta-independent"), ("reacher", "ddpg-normal")]
    # pendulum: 10 s + 6,000 steps x 1 ms per method; reacher: the same, its steps twice pendulum's cost
    assert "estimated total: 76 s CPU, 76 s wall" in out
    assert out.count("estimated: ") == 4 and not (tmp_path / "runs").exists()
