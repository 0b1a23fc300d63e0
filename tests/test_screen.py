"""experiments.screen: every variant changes what it says on the screen's tasks, and a tiny Pendulum screen
runs, skips what is done, and reports against the control and each noise baseline."""

import copy
import json
import os
import shutil

import pytest

from experiments import ablation, screen
from experiments.analysis import cells
from experiments.run import build_parser
from experiments.training import screen_variants
from experiments.training.args import config_from_run_args, run_args
from metapg_jax.config import to_dict

# tests/test_reproduce.py's TINY settings (its cells of the same method share these cells' programs).
TINY = ["run.eval_every=300", "ddpg.hidden=16,16", "meta.hidden=16,16", "run.eval_episodes=2",
        "meta.visit_samples=64", "ddpg.batch_size=16", "run.buffer_size=900"]


def _config(task, method):
    argv = [f"--env={task}", *method.options(), "--preset=paper", "--physics=mujoco", "--steps=300000",
            "--out=/dev/null"]
    return config_from_run_args(run_args(build_parser().parse_args(argv)))


@pytest.mark.parametrize("task", ["hopper", "halfcheetah"])
def test_each_variant_changes_the_config_it_names_and_nothing_else(task):
    control = _config(task, screen.cell_options(task, screen.CONTROL, "mujoco"))
    changed = {}
    for name in screen.VARIANTS:
        options = screen.cell_options(task, name, "mujoco")
        if options is None:
            continue
        cfg = _config(task, options)
        diff = ablation.config_diff(to_dict(cfg), to_dict(control))
        # A longer cycle (D2, a second D1 env) moves the evaluation interval to a multiple of it.
        assert "run.eval_every" not in diff or cfg.steps_per_cycle != control.steps_per_cycle, name
        changed[name] = {k: v for k, v in diff.items() if k != "run.eval_every"}
    assert changed[screen.CONTROL] == {}
    assert set(changed["normalised-reward"]) == {"meta.normalize_meta_reward"}
    assert set(changed["student-from-lookahead"]) == {"meta.student_from"}
    assert changed["log-std-floor"] == {"meta.min_log_std": (screen_variants.LOG_STD_FLOOR, -5.0)}
    assert changed["fresh-baseline"] == {"meta.baseline": ("fresh", "lookahead")}
    assert changed["two-d1-envs"] == {"meta.eval_envs": (2, 1)}
    # DDPG's 50 updates per 100 stored steps: half the Meta cycle, with the look-ahead's updates kept.
    cycle = control.steps_per_cycle
    assert changed["ddpg-update-ratio"]["run.train_steps"] == (cycle // 2, control.run.train_steps)
    assert changed["ddpg-update-ratio"]["meta.lookahead_steps"][0] == control.run.train_steps
    assert changed["ddpg-paramnoise"]["run.method"] == ("ddpg", "meta")
    assert changed["variance-teacher"] == {"meta.teacher": ("variance", "independent")}
    assert changed["teacher-lr-1e-3"] == {"meta.lr": (1e-3, 1e-4)}
    assert changed["frozen-teacher"] == {"meta.lr": (0.0, 1e-4)}
    assert changed["schedule-frozen"] == {**changed["ddpg-update-ratio"], **changed["frozen-teacher"]}
    if task == "hopper":  # the preset already takes one teacher step per cycle
        assert "one-teacher-step" not in changed and screen.same_as(task, "one-teacher-step", "mujoco") == ""
        # ... so the combination is the update-ratio cell, not run twice.
        assert "schedule" not in changed and screen.same_as(task, "schedule", "mujoco") == "ddpg-update-ratio"
    else:
        assert changed["one-teacher-step"] == {"meta.teacher_steps": (1, 100)}
        assert changed["schedule"] == {**changed["ddpg-update-ratio"], **changed["one-teacher-step"]}
    assert all(screen.same_as(task, n, "mujoco") is None for n in changed)


@pytest.mark.slow
def test_tiny_screen_runs_skips_and_reports(tmp_path, capsys):
    runs, results = str(tmp_path / "runs"), str(tmp_path / "results")
    argv = ["--tasks=pendulum", "--variants=paper-teacher,ddpg-normal",
            "--steps=900", "--seeds=2", f"--runs-dir={runs}", f"--results-dir={results}", "--quiet"]
    argv += [f"--set={s}" for s in TINY]
    assert screen.main(argv) == 0
    with open(os.path.join(results, "screen.json")) as f:
        summary = json.load(f)["tasks"]["pendulum"]
    assert set(summary["finished"]) == {"paper-teacher", "ddpg-normal"}
    assert "fresh-baseline" in summary["not_finished"]
    # The archived cell carries the grid's provenance and the run's own numbers.
    cell = os.path.join(results, "cells", "pendulum", "paper-teacher")
    with open(os.path.join(cell, "reproduce.json")) as f:
        assert len(json.load(f)["commit"]) == 40
    with open(os.path.join(cell, "summary.json")) as f:
        assert summary["finished"]["paper-teacher"]["finals"] == pytest.approx(
            json.load(f)["final_return_per_seed"])
    with open(os.path.join(results, "README.md")) as f:
        text = f.read()
    # a verdict column per reference, each a family over the tasks (no baseline picked by its mean)
    assert all(f"vs {screen.VARIANTS[b].label} |" in text for b in screen.BASELINES)
    assert set(summary["finished"]["paper-teacher"]["verdicts"]) == {"ddpg-normal"}  # param noise: not run
    assert set(summary["finished"]["ddpg-normal"]["verdicts"]) == {"paper-teacher"}
    judged = summary["finished"]["ddpg-normal"]["verdicts"]["paper-teacher"]
    assert judged["verdict"] in ("better", "worse", "equivalent", "inconclusive") and "p_holm" in judged
    with open(os.path.join(results, "aggregate.json")) as f:
        assert json.load(f)["tasks"] == ["pendulum"]
    assert "Not run (or not finished) yet:" in text and "fresh R_hat(pi)" in text
    assert os.path.exists(os.path.join(results, "pendulum", "curves.png"))
    capsys.readouterr()
    # A second call trains nothing.
    assert screen.main(argv) == 0
    out = capsys.readouterr().out
    assert out.count("done, skipped") == 2 and "running:" not in out


def test_bad_input_is_one_line_before_anything_trains(tmp_path, capsys):
    base = [f"--runs-dir={tmp_path}/r", f"--results-dir={tmp_path}/s", "--tasks=pendulum"]
    assert screen.main(base + ["--variants=nope"]) == 2
    assert "unknown variant 'nope'" in capsys.readouterr().err
    assert screen.main(base + ["--steps=1000"]) == 2  # not a whole number of Meta cycles (300 steps)
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: pendulum/paper-teacher:") and "\n" not in err
    assert not os.path.exists(f"{tmp_path}/r")



def test_the_committed_report_rebuilds_from_its_archive_byte_for_byte(tmp_path, monkeypatch):
    """``results/screen`` is what ``--report-only`` builds from ``results/screen/cells`` (its build provenance,
    stored in ``screen.json``, pinned)."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    committed = os.path.join(root, "results", "screen")
    with open(os.path.join(committed, "screen.json")) as f:
        stored = json.load(f)
    shutil.copytree(os.path.join(committed, "cells"), tmp_path / "results" / "screen" / "cells")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(cells, "build_info", lambda runs_dir: copy.deepcopy(stored["build"]))
    argv = ["--report-only", "--results-dir=results/screen", f"--steps={stored['upto']}",
            f"--seeds={stored['seeds']}", "--tasks=" + ",".join(stored["tasks"])]
    assert screen.main(argv) == 0
    out = tmp_path / "results" / "screen"
    written = sorted(str(p.relative_to(out)) for p in out.rglob("*")
                     if p.is_file() and p.relative_to(out).parts[0] != "cells" and p.suffix != ".png")
    assert "README.md" in written and "screen.json" in written
    for name in written:
        with open(os.path.join(committed, name), "rb") as f:
            assert (out / name).read_bytes() == f.read(), name
