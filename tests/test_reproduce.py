"""experiments.reproduce: bad input, the plan checked before the first cell runs, a tiny pendulum grid end to end (run,
skip what is done, resume), a grid stopped by SIGTERM (its cell checkpointed within the grace, no report, resumed),
the TD3 and C-engine grids' folders, TensorBoard, and a call from a dirty tree."""

import json
import os
import re
import shutil
import signal
import sys

import numpy as np
import pytest

from experiments import reproduce
from experiments.training import grid_cells
from experiments.analysis import cells
from experiments.grid.spec import GridRun, GridSpec
from tests.helpers import fabricate_run

# The same settings as tests/test_screen.py's, with a fixed replay capacity: the two files' pendulum cells of
# the same method run one program whatever their budget (the session's compile cache compiles it once).
TINY = ["--set", "run.eval_every=300", "--set", "ddpg.hidden=16,16", "--set", "meta.hidden=16,16",
        "--set", "run.eval_episodes=2", "--set", "meta.visit_samples=64", "--set", "ddpg.batch_size=16",
        "--set", "run.buffer_size=900"]


def test_reproduce_rejects_bad_input(capsys):
    assert reproduce.main(["--tasks", "cartpole"]) == 2
    assert "unknown task 'cartpole'" in capsys.readouterr().err
    assert reproduce.main(["--methods", "sac"]) == 2
    assert reproduce.main(["--seeds", "0"]) == 2
    assert reproduce.main(["--term-grace", "-5", "--dry-run"]) == 2
    assert "--term-grace must be a finite number of seconds >= 0" in capsys.readouterr().err


def test_the_run_order_lists_each_of_the_grids_tasks_once():
    from experiments.grid import methods as grid

    assert sorted(reproduce.RUN_ORDER) == sorted(grid.tasks()) and len(set(reproduce.RUN_ORDER)) == len(grid.tasks())


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
    assert reproduce.main([*base, "--methods", "ddpg-paramnoise,meta-independent", "--steps", "1000", "--seeds", "2",
                           "--dry-run"]) == 0
    assert "plan: 1 done, 1 new" in capsys.readouterr().out


@pytest.mark.slow
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
    assert out.count("--steps=900000") == 2 and "plan: 2 extend" in out
    # A cell whose evaluation interval is not the one a run at the requested budget gets is not extended.
    assert reproduce.main(argv + ["--steps", "1200", "--set", "run.eval_every=600", "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert out.count("its evaluation interval 300 is not the 600 of a run at that budget") == 2
    assert "plan: 2 done" in out

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
    grid_cells.write_cell_record(str(cell), ["--resume"], 0, 1.0, {"commit": "f" * 40, "dirty": True})
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
    assert "plan: 1 done" in out
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


@pytest.mark.slow
def test_a_grid_stopped_by_sigterm_checkpoints_its_cell_builds_no_report_and_resumes_the_cell(tmp_path, capsys,
                                                                                               monkeypatch):
    """A SIGTERM while the cell's first chunk is recorded: within the default grace the cell's run checkpoints the
    chunk, the grid exits 143 without building its report, and the same command resumes the cell to the numbers of
    an uninterrupted run. With ``--term-grace=0`` (passed on to the cell's run) it stops at once, with nothing
    checkpointed."""
    from experiments import run
    from metapg_jax.host import runfiles
    from metapg_jax.host.checkpoint import saved_steps
    from tests.helpers import assert_same_run

    write = runfiles.JsonlWriter.write

    def sigterm_in_the_first_chunk():
        def write_then_sigterm(self, rows):
            write(self, rows)
            if not getattr(write_then_sigterm, "sent", False):
                write_then_sigterm.sent = True
                os.kill(os.getpid(), signal.SIGTERM)

        monkeypatch.setattr(runfiles.JsonlWriter, "write", write_then_sigterm)

    def grid(name, *more):
        runs, results = tmp_path / name / "runs", tmp_path / name / "results"
        argv = ["--tasks", "pendulum", "--methods", "ddpg-paramnoise", "--seeds", "2", "--steps", "900", "--runs-dir",
                str(runs), "--results-dir", str(results), "--quiet", "--no-plot", *TINY, *more]
        return argv, runs / "paper" / "pendulum" / "ddpg-paramnoise", results

    argv, cell, results = grid("graced")
    sigterm_in_the_first_chunk()
    assert reproduce.main(argv) == 143
    monkeypatch.setattr(runfiles.JsonlWriter, "write", write)
    assert saved_steps(str(cell / "checkpoints")) == [1] and not (cell / "summary.json").exists()
    assert not (results / "table2.md").exists() and not (results / "README.md").exists()
    err = capsys.readouterr().err
    assert f"checkpointed after chunk 1 of 3; continue with: python -m experiments.run --resume {cell}" in err
    assert "grid stopped by SIGTERM: its report is not built; run the same command again to resume it" in err
    first = json.loads((cell / "reproduce.json").read_text())["calls"][0]
    assert first["status"] == 143 and not any(a.startswith("--term-grace") for a in first["argv"])
    assert reproduce.main(argv) == 0
    out = capsys.readouterr().out
    assert "resuming: python -m experiments.run" in out and "grid: 1 resumed" in out
    assert (results / "table2.md").exists()
    full = str(tmp_path / "uninterrupted")
    assert run.main([a for a in first["argv"] if a not in ("--out", str(cell))] + ["--out", full]) == 0
    assert_same_run(full, str(cell))

    argv, cell, results = grid("at-once", "--term-grace=0")
    sigterm_in_the_first_chunk()
    assert reproduce.main(argv) == 143
    assert saved_steps(str(cell / "checkpoints")) == [] and not (results / "table2.md").exists()
    assert "--term-grace=0" in json.loads((cell / "reproduce.json").read_text())["calls"][0]["argv"]
    assert "stopped by SIGTERM: chunk 1 of 3 was running and is lost; nothing of the run was checkpointed" in \
        capsys.readouterr().err


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
    cell = grid_cells.grid_cell(GridRun("runs", "results", tensorboard=True), GridSpec(), "pendulum", "meta-independent")
    for state in ("new", "resume", "extend"):
        assert "--tensorboard" in grid_cells.cell_argv(cell, str(tmp_path), state)
    plain = grid_cells.grid_cell(GridRun("runs", "results"), GridSpec(), "pendulum", "meta-independent")
    assert "--tensorboard" not in grid_cells.cell_argv(plain, str(tmp_path), "new")
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
        grid_cells.write_cell_record(str(out), ["--a"], 0, 1.0, started, diff)
        if method == "meta-independent":  # a second, clean call (a resume) adds no diff
            grid_cells.write_cell_record(str(out), ["--a"], 0, 1.0, {**started, "commit": "c-2", "dirty": False})
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


def test_a_ctrl_c_between_two_cells_stops_the_grid_also_when_started_in_the_background(monkeypatch, capsys):
    """A grid started by a shell in the background (SIGINT ignored, as ``cmd &`` leaves it) and sent SIGINT while
    it archives a finished cell or sets up the next: the next cell's run starts with the stop (it stops after its
    first chunk) or no cell starts; the grid exits 130."""
    import signal

    from metapg_jax.host import runner

    ran, started = [], []

    def run_cell(cell, plan):  # a run: its own loop's signals, then the grid's archive
        method = cell.name
        with runner.Signals() as loop:
            started.append((method, loop.requested))
        ran.append(method)
        if method == "a":
            signal.raise_signal(signal.SIGINT)  # while the finished cell is archived
        return 130 if loop.requested else 0

    def plan_cell(cell):
        if cell.name == "c":
            signal.raise_signal(signal.SIGINT)  # while the next cell is planned
        return {"argv": ["--x"], "state": "new", "archived": "nowhere", "message": "new"}

    monkeypatch.setattr(grid_cells, "run_cell", run_cell)
    monkeypatch.setattr(grid_cells, "plan_cell", plan_cell)
    cells_ = lambda *ms: [grid_cells.Cell(None, None, m, m, m) for m in ms]
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        assert grid_cells.run_cells(cells_("a", "b")) == (130, {"a": "ran"})
        out, err = capsys.readouterr()
        assert ran == ["a"] and "[2/2] b: not started (interrupted)" in err
        assert re.search(r"^grid: 1 cell\(s\) run in this call, \d+ s each on average; 1 cell\(s\) after this one, "
                         r"at most about \d+ s more at that rate$", out, re.M)
        ran.clear()
        started.clear()
        assert grid_cells.run_cells(cells_("b", "c", "d")) == (130, {"b": "ran", "c": "exit 130"})
        assert started == [("b", False), ("c", True)]
        assert "[2/3] c: interrupted; run the same command again to resume" in capsys.readouterr().err
        ran.clear()

        def terminated_while_archived(cell, plan):  # the record and archive end first
            ran.append(cell.name)
            signal.raise_signal(signal.SIGTERM)
            return 0

        monkeypatch.setattr(grid_cells, "run_cell", terminated_while_archived)
        assert grid_cells.run_cells(cells_("a", "b")) == (143, {"a": "ran"})
        assert ran == ["a"] and "[1/2] a: stopped by SIGTERM; run the same command again" in capsys.readouterr().err
        assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, old)
