"""experiments.run: bad input fails fast with one line and exit 2; a tiny run writes its artefacts."""

import json
import os
import re
import shutil
import subprocess
import sys

import pytest

from experiments import run
from experiments.training import args as training_args
from metapg_jax.host.driver import record_extension
from metapg_jax.host.checkpoint import saved_steps
from tests.helpers import TINY_BUFFER, TINY_RUN, assert_same_run, run_subprocess, wait_for_chunks

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.parametrize("argv,message", [
    (["--env=cartpole"], "unknown task 'cartpole'"),
    (["--method=sac"], "unknown method 'sac'"),
    (["--preset=fast"], "unknown preset 'fast'"),
    (["--noise=brown", "--method=ddpg"], "unknown noise 'brown'"),
    (["--noise=pink", "--method=own"], "--method=own samples the student's own stochastic policy, and --student=ddpg is deterministic"),
    (["--noise=mixed", "--method=own", "--student=sac"], "--noise=mixed is not a policy's sampling noise"),
    (["--noise=adaptive-param", "--method=own", "--student=sac"], "--noise=adaptive-param is not a policy's sampling noise"),
    (["--method=ddpg", "--student=sac"], "--student=sac explores with its own stochastic policy: use --method=own"),
    (["--method=ddpg", "--noise=pink", "--set", "pink.beta=-1"], "pink.beta must be a finite number >= 0"),
    (["--teacher=oracle"], "unknown teacher 'oracle'"),
    (["--seeds=0"], "--seeds must be positive"),
    (["--steps=-5"], "--steps must be positive"),
    (["--steps=1234", "--method=ddpg"], "not a multiple of the 100 env steps"),
    (["--steps=1000", "--method=ddpg", "--set", "run.eval_every=250"], "run.eval_every=250 is not a multiple"),
    (["--steps=1000", "--method=ddpg", "--set", "run.eval_every=300"], "e.g. use --steps=900"),
    (["--set", "ddpg.actor_lr=-1"], "ddpg.actor_lr must be a positive finite number"),
    (["--set", "ddpg.actor_lr=nan"], "ddpg.actor_lr must be a positive finite number"),
    (["--set", "ddpg.batch_size=0"], "ddpg.batch_size must be a positive"),
    (["--set", "ddpg.nope=1"], "unknown config field 'ddpg.nope'"),
    (["--set", "ddpg.batch_size=abc"], "expected int"),
    (["--set", "novalue"], "--set expects GROUP.FIELD=VALUE"),
    (["--method=ddpg", "--teacher=variance"], "--teacher applies to --method=meta only"),
    (["--noise=ou"], "--noise applies to --method=ddpg or own only"),
    (["--seed=-1"], "--seed must be in [0, 2**32)"),
    ([f"--seed={2 ** 63}"], "--seed must be in [0, 2**32)"),
    (["--set", "preset=modern"], "preset cannot be overridden with --set; choose it with the command's preset"),
    (["--set", "env.name=hopper"], "env.name cannot be overridden with --set; choose it with the command's task"),
    (["--set", "run.method=ddpg"], "run.method cannot be overridden with --set"),
    (["--method=ddpg", "--preset=modern", "--steps=3000"], "run.warmup_steps=5000 is not below the budget"),
    (["--method=ddpg", "--steps=1000", "--set", "ddpg.batch_size=2000"], "larger than the replay capacity 1000"),
    (["--method=ddpg", "--set", "noise.adapt_coef=0.5"], "noise.adapt_coef must be a finite number >= 1"),
    (["--method=ddpg", "--noise=ou", "--set", "noise.ou_dt=-1"], "noise.ou_dt must be a positive finite number"),
    (["--method=ddpg", "--noise=ou", "--set", "noise.ou_theta=nan"], "noise.ou_theta must be a finite number >= 0"),
    (["--set", "ddpg.final_init=nan"], "ddpg.final_init must be a finite number >= 0"),
    (["--compile-cache", os.path.abspath(__file__)], "is a file, not a folder; pass --compile-cache DIR or off"),
    (["--compile-cache", ""], "--compile-cache needs a folder (or 'off')"),
    (["--term-grace=-1"], "--term-grace must be a finite number of seconds >= 0 (0: a SIGTERM stops at once), got -1"),
    (["--term-grace=nan"], "--term-grace must be a finite number of seconds >= 0"),
    (["--checkpoint-minutes=0"], "--checkpoint-minutes must be > 0, got 0"),
    (["--physics-threads=0"], "--physics-threads must be a whole number >= 1, got '0'"),
    (["--physics-threads=two"], "--physics-threads must be a whole number >= 1, got 'two'"),
])
def test_bad_input_exits_2_with_one_line(argv, message, capsys):
    assert run.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and message in err[0], err


def test_existing_output_needs_overwrite(tmp_path, capsys):
    out = tmp_path / "run"
    out.mkdir()
    (out / "metrics.jsonl").write_text("{}\n")
    assert run.main(["--out", str(out)]) == 2
    assert "exists; pass --resume" in capsys.readouterr().err


def test_output_that_is_a_file_is_refused(tmp_path, capsys):
    path = tmp_path / "a_file"
    path.write_text("x")
    assert run.main(["--out", str(path)]) == 2
    assert "is a file, not a folder" in capsys.readouterr().err


def test_resume_without_a_checkpoint_fails_before_touching_the_run(tmp_path, capsys):
    """An empty checkpoints/ (a run killed before its first checkpoint) has nothing to resume: refused before
    an extension rewrites config.json."""
    out = str(tmp_path / "run")
    _stored_run(out, ["--env=pendulum", "--method=meta", "--steps=3000", "--out", out])
    shutil.rmtree(os.path.join(out, "checkpoints", "1"))
    before = open(os.path.join(out, "config.json")).read()
    for argv in (["--resume", out], ["--resume", out, "--steps=6000"]):
        assert run.main(argv) == 2
        assert "no checkpoint under" in capsys.readouterr().err
    assert open(os.path.join(out, "config.json")).read() == before


def test_help_documents_every_option():
    text = run.build_parser().format_help()
    for opt in ("--env", "--seeds", "--method", "--teacher", "--preset", "--noise", "--steps", "--seed",
                "--out", "--set", "--source", "--overwrite", "--compile-cache"):
        assert opt in text


def test_tiny_meta_run_end_to_end(tmp_path):
    out = tmp_path / "meta"
    cmd = [sys.executable, "-m", "experiments.run", *(a for a in TINY_RUN if a != "--no-plot"), *TINY_BUFFER,
           "--steps=600", "--out", str(out)]
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600,
                         env={**os.environ, "JAX_PLATFORMS": "cpu"})
    assert res.returncode == 0, res.stderr[-3000:]
    assert "final return" in res.stdout and "mean ± sample std over 2 seeds" in res.stdout
    for name in ("config.json", "metrics.jsonl", "cycles.jsonl", "summary.json", "learning_curve.png", "teacher.png",
                 "policy.npz", "checkpoints",
                 "visits.npz"):
        assert (out / name).exists(), name
    rows = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    assert len(rows) == 2 * 2 and {r["seed"] for r in rows} == {0, 1}
    assert rows[-1]["env_steps"] == 600
    summary = json.loads((out / "summary.json").read_text())
    from experiments.analysis import stats
    from metapg_jax.host import metric_rows

    train_s, exact = metric_rows.training_seconds(rows)
    assert exact and all(r["chunk_seconds"] > 0 for r in rows) and 0 < train_s <= summary["train_seconds"]
    # summary.json's final return is the tables' (experiments.analysis.stats) on the same metrics file.
    finals = stats.final_returns(metric_rows.curves(rows)[1])
    assert summary["final_return_per_seed"] == pytest.approx(finals.tolist())
    assert (summary["final_return_mean"], summary["final_return_std"]) == pytest.approx(stats.mean_std(finals))
    assert summary["last_eval_return_per_seed"] == pytest.approx([r["eval_return"] for r in rows[-2:]])
    import numpy as np

    visits = np.load(out / "visits.npz")
    assert visits["explore_early"].shape == (2, 16, 3) and int(visits["explore_count"][0]) == 2 * 100
    cycles = [json.loads(line) for line in (out / "cycles.jsonl").read_text().splitlines()]
    assert len(cycles) == 2 * (600 // 300) and "meta_reward" in cycles[0]


def _stored_run(out, argv):
    """A run folder as `prepare` sees one with a checkpoint: config.json and checkpoints/1 (an empty
    stand-in for orbax's step folder; nothing here restores it)."""
    args = run.build_parser().parse_args(argv)
    a = training_args.run_args(args)
    cfg = training_args.config_from_run_args(a)
    os.makedirs(os.path.join(out, "checkpoints", "1"))
    with open(os.path.join(out, "config.json"), "w") as f:
        json.dump({"run_args": a, "config": run.config_lib.to_dict(cfg)}, f)
    return cfg


def test_an_extension_keeps_a_budget_derived_evaluation_interval(tmp_path, capsys):
    """Where the default interval follows the budget (here under ten task intervals), extending keeps the stored one."""
    out = str(tmp_path / "run")
    short = _stored_run(out, ["--env=pendulum", "--method=meta", "--steps=3000", "--out", out])
    longer = training_args.config_from_run_args({**training_args.RUN_ARGS, "env": "pendulum", "method": "meta", "steps": 9000})
    assert longer.run.eval_every != short.run.eval_every        # else this test checks nothing
    cfg, a, _, resume, extend_from = run.prepare(run.build_parser().parse_args(["--resume", out, "--steps=9000"]))
    assert resume and extend_from == 3000
    assert cfg.run.total_steps == 9000 and cfg.run.eval_every == short.run.eval_every
    assert f"run.eval_every={short.run.eval_every}" in a["overrides"]  # stored with the extension
    # An interval given explicitly is a change like any other.
    assert run.main(["--resume", out, "--steps=9000", "--set", f"run.eval_every={longer.run.eval_every}"]) == 2
    assert "would also change: run.eval_every" in capsys.readouterr().err
    # As `experiments.run` records it before training: a later plain --resume continues the extension.
    record_extension(out, cfg, a, 3000)
    cfg2, a2, _, _, extend_from = run.prepare(run.build_parser().parse_args(["--resume", out]))
    assert extend_from is None and cfg2 == cfg and a2["overrides"] == a["overrides"]
    # A budget the stored interval does not divide is refused with the reason.
    other = str(tmp_path / "other")
    assert _stored_run(other, ["--env=pendulum", "--method=meta", "--steps=6000", "--out", other]).run.eval_every == 600
    assert run.main(["--resume", other, "--steps=9900"]) == 2
    assert "evaluation interval, 600 env steps, does not divide --steps=9,900" in capsys.readouterr().err


def test_a_run_too_large_for_memory_is_refused_before_compiling(tmp_path, capsys):
    """--seeds=100000000 on pendulum (a 900k-step replay buffer each) is refused with one line, needed vs
    available, from the state's shapes alone: nothing compiles and no folder is made. A sweep likewise."""
    from experiments import sweep

    out = tmp_path / "big"
    assert run.main(["--env=pendulum", "--method=ddpg", "--seeds=100000000", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --seeds=100000000 of pendulum ddpg/adaptive-param"), err
    assert "needs about" in err[0] and "PiB of memory" in err[0] and "GiB available" in err[0]
    assert not out.exists()
    assert sweep.main(["--env=pendulum", "--method=ddpg", "--seeds=50000000", "--grid", "ddpg.tau=0.01,0.02",
                       "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the sweep's group 1 (2 settings x 50000000 seeds" in err[0] and "available" in err[0]
    assert not out.exists()


@pytest.mark.slow
def test_sigterm_without_a_grace_before_the_first_checkpoint_says_nothing_was_saved(tmp_path):
    """SIGTERM with --term-grace=0 while the first chunk runs: exit 143 at once, with one line saying that nothing
    can be resumed and the command that starts the run again."""
    import signal

    out = tmp_path / "run"
    argv = [*TINY_RUN, *TINY_BUFFER, "--steps=270000", "--term-grace=0", "--quiet", "--no-plot", "--out", str(out)]
    proc = subprocess.Popen([sys.executable, "-m", "experiments.run", *argv], cwd=ROOT, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env={**os.environ, "JAX_PLATFORMS": "cpu"})
    for line in proc.stdout:
        if line.startswith("compiled in"):
            break
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err[-2000:]
    line = err.strip().splitlines()[-1]
    # (The signal may land just before the loop starts its first chunk: "no chunk had started".)
    assert re.match(r"stopped by SIGTERM: (chunk \d+ of 900 was running and is lost|no chunk had started); nothing of "
                    r"the run was checkpointed, so it cannot be resumed; start again with: python -m experiments.run "
                    r"--env=pendulum", line), line
    assert line.endswith(f"--out {out} --overwrite")
    assert not any((out / "checkpoints").iterdir()) if (out / "checkpoints").exists() else True


@pytest.mark.slow
def test_sigterm_before_the_first_checkpoint_checkpoints_the_chunk_in_flight_and_resumes_to_the_same_numbers(
        tmp_path):
    """SIGTERM once a run (12 chunks of about 0.3 s, the default 5-minute cadence: no checkpoint before its end) has
    recorded 2 chunks: within the default grace it finishes the chunk in flight, checkpoints it, exits 143 with the
    line that says how to resume, and ``--resume`` ends with the numbers of an uninterrupted run, bit for bit."""
    import signal

    args = [*TINY_RUN, *TINY_BUFFER, "--steps=3600"]
    out = str(tmp_path / "stopped")
    proc = run_subprocess(args + ["--out", out])
    wait_for_chunks(proc, out, 2)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err[-2000:]
    done = saved_steps(os.path.join(out, "checkpoints"))
    assert len(done) == 1 and 2 <= done[0] < 12, done  # the one checkpoint: the stop's
    assert len(open(os.path.join(out, "metrics.jsonl")).readlines()) == 2 * done[0]
    line = err.strip().splitlines()[-1]
    assert re.fullmatch(rf"stopped by SIGTERM after \d+\.\d s of its 25 s grace: checkpointed after chunk {done[0]} of "
                        rf"12; continue with: python -m experiments.run --resume {re.escape(out)}", line), line
    assert run.main(["--resume", out, "--quiet", "--no-plot"]) == 0
    full = str(tmp_path / "full")
    assert run.main(args + ["--out", full]) == 0
    assert_same_run(full, out)


def test_a_resume_keeps_the_stored_engine(tmp_path):
    """--physics=auto (the default) is stored resolved; a resume keeps the stored engine, also for a run
    stored before --physics existed (its config's engine); an explicit --physics wins for a new run."""
    out = str(tmp_path / "mjx")
    _stored_run(out, ["--env=hopper", "--physics=mjx", "--steps=3000", "--out", out])
    cfg, a, *_ = run.prepare(run.build_parser().parse_args(["--resume", out]))
    assert cfg.env.physics == "mjx" and a["physics"] == "mjx"
    cfg, a, *_ = run.prepare(run.build_parser().parse_args(["--env=hopper", "--out", str(tmp_path / "new")]))
    assert cfg.env.physics == "mujoco" and a["physics"] == "mujoco"  # auto on the CPU
    stored = json.load(open(os.path.join(out, "config.json")))
    del stored["run_args"]["physics"]
    json.dump(stored, open(os.path.join(out, "config.json"), "w"))
    cfg, a, *_ = run.prepare(run.build_parser().parse_args(["--resume", out]))
    assert cfg.env.physics == "mjx" and a["physics"] == "mjx"
