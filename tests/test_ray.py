"""experiments.reproduce --launcher ray: a tiny grid (one task, one method: one cell) on a local Ray instance
that the command starts itself, with the cell's worker killed once mid-run: Ray retries the cell, it
resumes from its last checkpoint, and the archive holds the numbers of an uninterrupted local run. (The
cell's program is compiled once: the retry and the local run load it from the pytest run's compile cache.)"""

import json
import os
import subprocess
import sys
import threading
import time

import pytest

ray = pytest.importorskip("ray")
psutil = pytest.importorskip("psutil")
pytestmark = pytest.mark.slow  # all Ray (tests/test_tiers.py)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TINY = ["--seeds", "2", "--steps", "1500", "--set", "run.eval_every=300", "--set", "ddpg.hidden=16,16",
        "--set", "run.eval_episodes=2", "--set", "meta.visit_samples=64", "--set", "ddpg.batch_size=16",
        "--set", "env.episode_length=60"]
TASKS, METHODS = ("pendulum",), ("ddpg-normal",)
GRID = ["--tasks", ",".join(TASKS), "--methods", ",".join(METHODS)]


def _kill_workers_once_checkpointed(runs, done, killed):
    """SIGKILL every Ray worker running a cell as soon as some cell has a checkpoint and no cell has finished."""
    cells = [os.path.join(runs, "paper", t, m) for t in TASKS for m in METHODS]
    while not done.is_set():
        checkpointed = any(os.path.isdir(os.path.join(c, "checkpoints")) and
                           any(d.isdigit() for d in os.listdir(os.path.join(c, "checkpoints"))) for c in cells)
        if checkpointed and not any(os.path.exists(os.path.join(c, "summary.json")) for c in cells):
            for p in psutil.process_iter(["cmdline"]):
                if any("ray::_ray_cell" in part for part in (p.info["cmdline"] or [])):
                    p.kill()
                    killed.append(p.pid)
            if killed:
                return
        time.sleep(0.1)


def test_the_grid_on_a_local_ray_instance_survives_killed_workers(tmp_path):
    runs, results = str(tmp_path / "runs"), str(tmp_path / "results")
    argv = [sys.executable, "-m", "experiments.reproduce", "--launcher", "ray", *GRID, *TINY, "--checkpoint-every", "1",
            "--runs-dir", runs, "--results-dir", results, "--no-plot", "--quiet", "--embedding", "pca"]
    env = {**os.environ, "PYTHONPATH": ROOT, "RAY_DEDUP_LOGS": "0"}
    done, killed = threading.Event(), []
    killer = threading.Thread(target=_kill_workers_once_checkpointed, args=(runs, done, killed), daemon=True)
    killer.start()
    try:
        proc = subprocess.run(argv, cwd=str(tmp_path), env=env, capture_output=True, text=True, timeout=900)
    finally:
        done.set()
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, log[-4000:]
    assert killed, "no worker was killed: the test did not test a failure"
    assert "Started a local Ray instance" in log and "resumed after" in log
    for task in TASKS:
        for method in METHODS:
            archived = os.path.join(results, "cells", task, method)
            summary = json.load(open(os.path.join(archived, "summary.json")))
            assert summary["env_steps"] == 1500 and summary["num_seeds"] == 2
            record = json.load(open(os.path.join(archived, "reproduce.json")))
            assert record["calls"][-1]["status"] == 0
            rows = [json.loads(line) for line in open(os.path.join(archived, "metrics.jsonl"))]
            assert sorted((r["seed"], r["chunk"]) for r in rows) == [(s, c) for s in range(2) for c in range(5)]
    table = json.load(open(os.path.join(results, "table2.json")))
    assert {r["task"] for r in table["rows"] if r["methods"]["ddpg-normal"]["status"] == "done"} == set(TASKS)

    # A killed cell's call left no record; the retry resumed it from its checkpoint (its first recorded call
    # is a --resume), and its numbers equal an uninterrupted local run of the same cell.
    resumed = []
    for task in TASKS:
        for method in METHODS:
            archived = os.path.join(results, "cells", task, method)
            first = json.load(open(os.path.join(archived, "reproduce.json")))["calls"][0]["argv"]
            if "--resume" in first:
                resumed.append((archived, first[:first.index("--resume")]))
    assert resumed, "no cell was resumed from a checkpoint"
    archived, options = resumed[0]
    local = str(tmp_path / "local")
    options = [a for a in options if not a.startswith("--checkpoint")]
    from experiments import run

    assert run.main([*options, "--out", local]) == 0  # in this process: the cell's program from the compile cache
    numbers = lambda path: sorted((r["seed"], r["chunk"], r["eval_return"], r["critic_loss"])
                                  for r in map(json.loads, open(os.path.join(path, "metrics.jsonl"))))
    assert numbers(archived) == numbers(local)
