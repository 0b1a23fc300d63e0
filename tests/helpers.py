"""Tiny configurations for fast tests (pendulum, small networks, short chunks), and fabricated run folders."""

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from metapg_jax import config as config_lib
from metapg_jax import strategy
from metapg_jax.config import make_config


def isolated_registry(monkeypatch) -> None:
    """Registrations a test makes (``metapg_jax.strategy.register_*``) are gone after it."""
    strategy.load_builtins()
    monkeypatch.setattr(strategy, "_STUDENTS", dict(strategy._STUDENTS))
    monkeypatch.setattr(strategy, "_EXPLORERS", dict(strategy._EXPLORERS))
    monkeypatch.setattr(strategy, "_GROUPS", dict(strategy._GROUPS))
    from metapg_jax import action_noise

    monkeypatch.setattr(action_noise, "_KINDS", dict(action_noise._KINDS))


def gymnasium_make(gym_id: str):
    """``gymnasium.make(gym_id)``, the tests' reference, without MuJoCo's settotalmass deprecation warning
    landing in the working directory as MUJOCO_LOG.TXT (envs.mujoco_base.without_the_settotalmass_warning;
    the model is gymnasium's own, unchanged)."""
    import gymnasium

    from envs.mujoco_base import without_the_settotalmass_warning

    with without_the_settotalmass_warning():
        return gymnasium.make(gym_id)


ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# The tiny schedule every test run starts from: 16-16 networks, 300-step chunks, 60-step episodes, 50-step noise
# cycles and 150-step teacher cycles (50 + 100), 5 updates per cycle, 2 evaluation episodes.
TINY = {
    "run.eval_every": 300, "run.eval_episodes": 2, "ddpg.hidden": "16,16", "ddpg.batch_size": 16,
    "run.train_steps": 5, "meta.hidden": "16,16", "meta.explore_steps": 50, "meta.eval_steps": 100,
    "run.visit_samples": 64, "run.rollout_steps": 50, "env.episode_length": 60,
}


def tiny_config(method="ddpg", steps=600, eval_every=300, env="pendulum", physics="mjx", **overrides):
    """``make_config`` with the ``TINY`` schedule (and ``overrides``, dotted names as keyword arguments:
    ``tiny_config("meta", **{"meta.lr": 0.0})``)."""
    return make_config(env, method, steps=steps, overrides={**TINY, "run.eval_every": eval_every, **overrides},
                       physics=physics)


def tiny_argv(method="meta", env="pendulum", seeds=2, **overrides):
    """``experiments.run`` options of a run with the ``TINY`` schedule: ``--env``, ``--method`` (None: left out,
    for a plug-in's), ``--seeds``, ``--quiet --no-plot``, then one ``--set`` per field of ``TINY`` updated by
    ``overrides`` (dotted names as keyword arguments; a value of None drops the field)."""
    fields = {k: v for k, v in {**TINY, **overrides}.items() if v is not None}
    argv = [f"--env={env}", *([f"--method={method}"] if method else []), f"--seeds={seeds}", "--quiet", "--no-plot"]
    for k, v in fields.items():
        argv += ["--set", f"{k}={v}"]
    return argv


# A tiny Pendulum Meta run with the task's own teacher schedule (300-step cycles, 50 updates) and a fixed replay
# capacity, shared by the command-line tests: with the same capacity such runs compile to the same programs
# whatever their budget, so the session's compile cache (conftest.py) compiles them once for all the tests and
# subprocesses.
TINY_RUN = tiny_argv("meta", **{"ddpg.batch_size": None, "run.train_steps": None, "meta.explore_steps": None,
                                "meta.eval_steps": None, "run.rollout_steps": None, "env.episode_length": None,
                                "run.visit_samples": 16})
TINY_BUFFER = ["--set", "run.buffer_size=2700"]


def fabricate_run(path, task, method, values, steps, complete=True, visit_obs=None, seed=0):
    """A run folder like experiments.run writes: config.json, metrics.jsonl, (summary.json), (visits.npz); one seed
    per row of ``values`` from base seed ``seed``."""
    os.makedirs(path)
    kind = "meta" if method.startswith("meta") else "ddpg"
    cfg = config_lib.make_config(task, kind, steps=int(steps[-1]) if complete else 3 * int(steps[-1]))
    run_args = {"env": task, "method": kind, "teacher": None, "preset": "paper", "noise": None,
                "seeds": len(values), "seed": seed, "steps": None, "source": "gymnasium", "overrides": []}
    with open(os.path.join(path, "config.json"), "w") as f:
        json.dump({"config": config_lib.to_dict(cfg), "run_args": run_args, "jax_version": "x", "backend": "cpu",
                   "devices": ["cpu:0"]}, f)
    with open(os.path.join(path, "metrics.jsonl"), "w") as f:
        for c, step in enumerate(steps):
            for s in range(len(values)):
                f.write(json.dumps({"seed": s, "chunk": c, "env_steps": int(step), "eval_return": float(values[s][c])})
                        + "\n")
    if complete:
        with open(os.path.join(path, "summary.json"), "w") as f:
            json.dump({"env_steps": int(steps[-1]), "num_seeds": len(values), "train_seconds": 1.5,
                       "compile_seconds": 0.5}, f)
    if visit_obs is not None:
        rng = np.random.default_rng(len(str(path)))
        n, k = len(values), 40
        arrays = {f"{who}_{when}": rng.normal(size=(n, k, visit_obs)).astype(np.float32)
                  for who in ("explore", "student") for when in ("early", "late")}
        arrays["explore_count"] = np.full(n, 1000, np.int32)
        arrays["student_count"] = np.full(n, 1000 if kind == "meta" else 0, np.int32)
        np.savez(os.path.join(path, "visits.npz"), **arrays)


class UniformExplorer(strategy.Explorer):
    """Uniformly random actions forever (an explorer a user might write: one class, no loop edits)."""

    def init(self, trainer, student, key):
        import jax.numpy as jnp

        return {"steps": jnp.zeros((), jnp.int32)}

    def cycle(self, trainer, state):
        import jax

        from metapg_jax.rollout import completed_episode_mean, rollout

        key, k_roll, k_train = jax.random.split(state.key, 3)
        policy = lambda carry, obs, first, k: (trainer.random_action(k), carry, None)
        env_state, _, transitions, stats, _ = rollout(trainer.env, policy, state.env_state, None, k_roll,
                                                      trainer.config.run.rollout_steps)
        state = trainer.store(state.replace(env_state=env_state, key=key), transitions)
        state, metrics = trainer.student_updates(state, k_train, trainer.config.run.train_steps)
        steps = state.explorer["steps"] + transitions.reward.shape[0]
        return state.replace(explorer={"steps": steps}), {
            **metrics, "train_return": completed_episode_mean(stats)[0], "uniform_steps": steps}


def metrics_rows(out):
    """A run's metrics.jsonl rows without their timings."""
    rows = [json.loads(line) for line in open(os.path.join(out, "metrics.jsonl"))]
    for r in rows:
        r.pop("wall_time"), r.pop("chunk_seconds")
    return rows


def policy_arrays(out):
    with np.load(os.path.join(out, "policy.npz")) as f:
        return {k: f[k] for k in f.files if k != "description"}


def assert_same_run(a, b):
    """Two run folders hold the same metrics (timings aside) and the same exported policies, bit for bit."""
    assert metrics_rows(a) == metrics_rows(b)
    pa, pb = policy_arrays(a), policy_arrays(b)
    assert pa.keys() == pb.keys()
    for k in pa:
        np.testing.assert_array_equal(pa[k], pb[k], err_msg=k)


def run_subprocess(args, **kw):
    """``python -m experiments.run ARGS`` started in the repository root (``env``: variables to add)."""
    # The child inherits JAX_PLATFORMS (conftest.py defaults it to cpu): a killed run resumed on another
    # backend than the in-process reference run's would differ from it in round-off.
    env = {**os.environ, **kw.pop("env", {})}
    return subprocess.Popen([sys.executable, "-m", "experiments.run", *args], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


def wait_for_chunks(proc, out, chunks, seeds=2):
    """Returns once the run ``proc`` writes into ``out`` has ``chunks`` chunks of ``seeds`` seeds in its
    metrics.jsonl (fails the test if it ends before, or after 300 s)."""
    metrics = os.path.join(out, "metrics.jsonl")
    deadline = time.time() + 300
    while time.time() < deadline:
        if os.path.exists(metrics) and sum(1 for _ in open(metrics)) >= chunks * seeds:
            return
        if proc.poll() is not None:
            pytest.fail("the run ended before it could be stopped: " + proc.stderr.read()[-2000:])
        time.sleep(0.05)
    pytest.fail(f"the run did not write {chunks} chunks in 300 s")


def sigkill_resume_and_compare(tmp_path, args, chunks, resume_args=()):
    """Runs ``args`` (2 seeds, a checkpoint per chunk) in a subprocess, SIGKILLs it once 2 chunks are in
    metrics.jsonl, resumes it in another process, and asserts it equals the uninterrupted run."""
    out = str(tmp_path / "killed")
    proc = run_subprocess(args + ["--out", out])
    wait_for_chunks(proc, out, 2)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    from experiments import run
    from metapg_jax.host.checkpoint import Checkpointer

    done = Checkpointer(os.path.join(out, "checkpoints")).steps()
    assert done and done[-1] < chunks, done
    res = run_subprocess(["--resume", out, "--quiet", "--no-plot", *resume_args])
    _, err = res.communicate(timeout=600)
    assert res.returncode == 0, err[-3000:]
    full = str(tmp_path / "full")
    assert run.main(args + ["--out", full]) == 0
    assert_same_run(full, out)
    return full


def assert_run_refuses(argv, message, tmp_path, capsys) -> None:
    """``experiments.run`` with ``argv`` (writing to ``tmp_path/x``) exits 2 within seconds, nothing traced or
    compiled: one line on stderr starting with ``message``, and no output folder."""
    from experiments import run

    t0 = time.perf_counter()
    assert run.main(argv + ["--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(message) and len(err.splitlines()) == 1, err
    assert not (tmp_path / "x").exists()
    assert time.perf_counter() - t0 < 5  # nothing was traced or compiled


def rewind_resume_and_compare(tmp_path, args):
    """Runs ``args`` (a checkpoint per chunk) in this process, keeps a copy of its outputs, rewinds the run
    to the checkpoint before its last chunk (the last one deleted, as a run killed in its last chunk leaves
    it), resumes it in this process and asserts it equals the copy: the state a checkpoint holds continues
    the run bit for bit. (Killing a process mid-run is tested once, ``sigkill_resume_and_compare``.)"""
    import shutil

    from experiments import run
    from metapg_jax.host.checkpoint import Checkpointer

    out, full = str(tmp_path / "rewound"), str(tmp_path / "full")
    assert run.main(args + ["--out", out]) == 0
    shutil.copytree(out, full)
    checkpoints = Checkpointer(os.path.join(out, "checkpoints"))
    last = checkpoints.steps()[-1]
    checkpoints.manager.delete(last)
    checkpoints.close()
    os.remove(os.path.join(out, "summary.json"))
    assert run.main(["--resume", out, "--quiet", "--no-plot"]) == 0
    assert_same_run(full, out)
    return full
