"""experiments.sweep / metapg_jax.sweep: settings x seeds in one program equal separate runs of the
settings (up to float32 round-off: the batch shape differs), structural fields get programs of their
own, bad input is refused before anything compiles, and a sweep interrupted by Ctrl-C or SIGTERM resumes bit for bit."""

import json
import os
import signal

import numpy as np
import pytest

import envs
from experiments import run, sweep
from experiments.training.args import RUN_ARGS
from metapg_jax.host import runfiles
from metapg_jax.sweep import structural_fields
from tests.helpers import tiny_argv, tiny_config

# A fixed replay capacity: the sweeps below run one program whatever their budget (the pytest run's compile
# cache, conftest.py, compiles it once).
TINY = [*tiny_argv("meta", **{"run.buffer_size": 900}), "--steps=600"]
GRID = ["--grid", "meta.lr=1e-4,1e-2", "--grid", "ddpg.tau=0.01,0.5"]


def _rows(path):
    return runfiles.read_jsonl(os.path.join(path, "metrics.jsonl"))


@pytest.mark.slow
def test_a_sweep_equals_separate_runs_of_its_settings(tmp_path):
    out = str(tmp_path / "sweep")
    assert sweep.main([*TINY, *GRID, "--out", out, "--no-plot"]) == 0
    stored = json.load(open(os.path.join(out, "sweep.json")))
    assert len(stored["settings"]) == 4 and len(stored["groups"]) == 1  # one program for all 4 x 2 runs
    assert stored["groups"][0]["batched"] == ["meta.lr", "ddpg.tau"]
    rows = _rows(out)
    assert sorted((r["setting"], r["seed"], r["chunk"]) for r in rows) == [
        (k, s, c) for k in range(4) for s in range(2) for c in range(2)]
    for k in (3,):  # (1e-2, 0.5): the corner furthest from the defaults
        values = stored["settings"][k]["values"]
        single = str(tmp_path / f"run{k}")
        argv = [*TINY, "--out", single]
        for field, value in values.items():
            argv += ["--set", f"{field}={value}"]
        assert run.main(argv) == 0
        mine = sorted((r["seed"], r["chunk"], r["eval_return"], r["critic_loss"]) for r in rows if r["setting"] == k)
        theirs = sorted((r["seed"], r["chunk"], r["eval_return"], r["critic_loss"]) for r in _rows(single))
        assert [m[:2] for m in mine] == [t[:2] for t in theirs]
        np.testing.assert_allclose([m[2:] for m in mine], [t[2:] for t in theirs], rtol=1e-4, atol=1e-3)
    losses = {k: np.array(sorted((r["seed"], r["chunk"], r["critic_loss"]) for r in rows if r["setting"] == k))[:, 2]
              for k in (0, 3)}
    assert np.abs(losses[0] - losses[3]).max() > 1e-2  # ... and the settings do differ
    summary = json.load(open(os.path.join(out, "summary.json")))["settings"]
    assert sum(bool(e.get("best")) for e in summary) == 1 and all(e["seeds"] == 2 and e["complete"] for e in summary)
    best = max(summary, key=lambda e: e["mean"])
    assert best.get("best") and best["ci95"][0] <= best["mean"] <= best["ci95"][1]
    assert "**best**" in open(os.path.join(out, "summary.md")).read()


def test_fields_that_change_the_program_are_found_and_split_into_programs(tmp_path):
    cfg = tiny_config("meta")
    env = envs.make("pendulum", episode_length=cfg.episode_length)
    fields = ["meta.lr", "meta.init_log_std", "ddpg.tau", "noise.stddev", "ddpg.hidden", "meta.teacher",
              "meta.teacher_steps", "run.train_steps", "meta.normalize_meta_reward"]
    assert structural_fields(cfg, env, fields) == ["ddpg.hidden", "meta.teacher", "meta.teacher_steps",
                                                   "run.train_steps", "meta.normalize_meta_reward"]
    a = {**RUN_ARGS, "seeds": 2, "steps": 600, "overrides": TINY[TINY.index("--set"):-1][1::2]}
    settings, configs, groups, _ = sweep.plan(a, {"meta.lr": ["1e-4", "1e-3"], "meta.teacher": ["independent", "variance"]})
    assert len(settings) == 4
    assert [(g["settings"], g["batched"], g["fixed"]) for g in groups] == [
        ([0, 2], ["meta.lr"], {"meta.teacher": "independent"}), ([1, 3], ["meta.lr"], {"meta.teacher": "variance"})]


@pytest.mark.parametrize("grid, message", [
    (["--grid", "meta.nope=1,2"], "unknown config field 'meta.nope'"),
    (["--grid", "meta.lr="], "empty value"),
    (["--grid", "meta.lr=1e-3,,1e-4"], "empty value"),
    (["--grid", "meta.lr=fast,slow"], "meta.lr"),
    (["--grid", "meta.lr=1e-3,1e-3"], "given twice"),
    (["--grid", "meta.visit_samples=8,16", "--grid", "run.visit_samples=8,32"], "names run.visit_samples twice"),
    (["--grid", "run.eval_every=300,600"], "both swept"),
    (["--grid", "run.method=ddpg,meta"], "cannot be overridden"),
    (["--grid", "meta.lr=-1,1e-3"], "meta.lr"),
    ([], "at least one --grid"),
])
def test_bad_grids_are_refused_before_compiling(grid, message, tmp_path, capsys):
    out = tmp_path / "sweep"
    assert sweep.main([*TINY, *grid, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and err.startswith("error: ") and len(err.strip().splitlines()) == 1
    assert not out.exists()


@pytest.mark.slow
def test_an_interrupted_sweep_resumes_to_the_numbers_of_an_uninterrupted_one(tmp_path, monkeypatch, capsys):
    """A Ctrl-C, and a SIGTERM (within its default grace), while the first chunk's rows are written: the chunk is
    checkpointed, exit 130 / 143, and ``--resume`` (after the SIGTERM: the same loop wrote both checkpoints) ends
    with the uninterrupted sweep's numbers. With ``--term-grace=0`` the SIGTERM stops the sweep at once, with nothing
    checkpointed."""
    grid = [*GRID, "--steps=900", "--no-plot"]
    whole = str(tmp_path / "whole")
    assert sweep.main([*TINY, *grid, "--out", whole]) == 0
    write = runfiles.JsonlWriter.write

    def interrupt(signum):
        def write_then_signal(self, rows):  # the signal while the first chunk's rows are written
            write(self, rows)
            if not getattr(write_then_signal, "sent", False):
                write_then_signal.sent = True
                os.kill(os.getpid(), signum)

        monkeypatch.setattr(runfiles.JsonlWriter, "write", write_then_signal)

    key = lambda r: (r["setting"], r["seed"], r["chunk"])
    strip = lambda rows: sorted(({k: v for k, v in r.items() if k not in ("wall_time", "chunk_seconds")}
                                 for r in rows), key=key)
    for signum, status in ((signal.SIGINT, 130), (signal.SIGTERM, 143)):
        part = str(tmp_path / f"part-{signum}")
        interrupt(signum)
        assert sweep.main([*TINY, *grid, "--out", part]) == status
        monkeypatch.setattr(runfiles.JsonlWriter, "write", write)
        assert not os.path.exists(os.path.join(part, "summary.json"))
        assert sorted(os.listdir(os.path.join(part, "groups", "0", "checkpoints"))) == ["1"]
        assert f"checkpointed after chunk 1 of 3 of group 1; continue with: python -m experiments.sweep --resume " \
               f"{part}" in capsys.readouterr().err
    assert sweep.main(["--resume", part, "--quiet", "--no-plot"]) == 0
    assert strip(_rows(part)) == strip(_rows(whole))
    assert json.load(open(os.path.join(part, "summary.json"))) == json.load(open(os.path.join(whole, "summary.json")))
    assert sweep.main(["--resume", part, "--grid", "meta.lr=1"]) == 2
    part = str(tmp_path / "part-at-once")
    interrupt(signal.SIGTERM)
    assert sweep.main([*TINY, *grid, "--term-grace=0", "--out", part]) == 143
    assert not os.listdir(os.path.join(part, "groups", "0", "checkpoints"))
    assert "stopped by SIGTERM: chunk 1 of 3 was running and is lost; nothing of group 1 was checkpointed" in \
        capsys.readouterr().err


def test_a_ctrl_c_between_two_groups_stops_the_sweep_before_the_next(tmp_path, monkeypatch, capsys):
    """A Ctrl-C after a group's loop ended (while it writes its last rows) is kept by the sweep: the next group does
    not start, exit 130, and the resume line is printed."""
    started = []

    def group_then_ctrl_c(out, g, *args, **kwargs):
        started.append(g)
        signal.raise_signal(signal.SIGINT)
        return 0

    monkeypatch.setattr(sweep, "run_group", group_then_ctrl_c)
    out = str(tmp_path / "sweep")
    assert sweep.main([*TINY, "--grid", "meta.teacher=independent,variance", "--out", out, "--no-plot"]) == 130
    assert started == [0]
    assert f"interrupted before group 2 of 2 started; continue with: python -m experiments.sweep --resume {out}" \
        in capsys.readouterr().err
    assert not os.path.exists(os.path.join(out, "summary.json"))
