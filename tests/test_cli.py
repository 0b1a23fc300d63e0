"""experiments.run: bad input fails fast with one line and exit 2; a tiny run writes its artefacts."""

import json
import os
import subprocess
import sys

import pytest

from experiments import run

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.parametrize("argv,message", [
    (["--env=cartpole"], "unknown task 'cartpole'"),
    (["--method=sac"], "unknown method 'sac'"),
    (["--preset=fast"], "unknown preset 'fast'"),
    (["--noise=pink", "--method=ddpg"], "unknown noise 'pink'"),
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


def test_help_documents_every_option():
    text = run.build_parser().format_help()
    for opt in ("--env", "--seeds", "--method", "--teacher", "--preset", "--noise", "--steps", "--seed",
                "--out", "--set", "--source", "--overwrite"):
        assert opt in text


def test_tiny_meta_run_end_to_end(tmp_path):
    out = tmp_path / "meta"
    cmd = [sys.executable, "-m", "experiments.run", "--env=pendulum", "--method=meta", "--seeds=2",
           "--steps=600", "--quiet", "--out", str(out), "--set", "run.eval_every=300",
           "--set", "ddpg.hidden=16,16", "--set", "meta.hidden=16,16", "--set", "run.eval_episodes=2",
           "--set", "meta.visit_samples=64"]
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600,
                         env={**os.environ, "JAX_PLATFORMS": "cpu"})
    assert res.returncode == 0, res.stderr[-3000:]
    assert "final eval return" in res.stdout and "mean ± std over 2 seeds" in res.stdout
    for name in ("config.json", "metrics.jsonl", "cycles.jsonl", "summary.json", "learning_curve.png", "teacher.png",
                 "policy.npz", "checkpoints",
                 "visits.npz"):
        assert (out / name).exists(), name
    rows = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    assert len(rows) == 2 * 2 and {r["seed"] for r in rows} == {0, 1}
    assert rows[-1]["env_steps"] == 600
    summary = json.loads((out / "summary.json").read_text())
    assert len(summary["final_eval_return_per_seed"]) == 2
    assert summary["final_eval_return_mean"] == pytest.approx(
        sum(summary["final_eval_return_per_seed"]) / 2, rel=1e-5)
    import numpy as np

    visits = np.load(out / "visits.npz")
    assert visits["explore_early"].shape == (2, 64, 3) and int(visits["explore_count"][0]) == 2 * 100
    cycles = [json.loads(line) for line in (out / "cycles.jsonl").read_text().splitlines()]
    assert len(cycles) == 2 * (600 // 300) and "meta_reward" in cycles[0]
