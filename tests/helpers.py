"""Tiny configurations for fast tests (pendulum, small networks, short chunks), and fabricated run folders."""

import json
import os

import numpy as np

from metapg_jax import config as config_lib
from metapg_jax.config import make_config


# experiments.run options of a tiny Pendulum Meta run, shared by the command-line tests. With the same
# replay capacity (``run.buffer_size``) such runs compile to the same programs whatever their budget, so
# the session's compile cache (conftest.py) compiles them once for all the tests and subprocesses.
TINY_RUN = ["--env=pendulum", "--method=meta", "--seeds=2", "--set", "run.eval_every=300",
            "--set", "ddpg.hidden=16,16", "--set", "meta.hidden=16,16", "--set", "run.eval_episodes=2",
            "--set", "meta.visit_samples=16"]
TINY_BUFFER = ["--set", "run.buffer_size=2700"]


def gymnasium_make(gym_id: str):
    """``gymnasium.make(gym_id)``, the tests' reference, without MuJoCo's settotalmass deprecation warning
    landing in the working directory as MUJOCO_LOG.TXT (envs.gym_mujoco.without_the_settotalmass_warning;
    the model is gymnasium's own, unchanged)."""
    import gymnasium

    from envs.gym_mujoco import without_the_settotalmass_warning

    with without_the_settotalmass_warning():
        return gymnasium.make(gym_id)


def tiny_config(method="ddpg", steps=600, eval_every=300, env="pendulum", physics="mjx", **overrides):
    base = {
        "run.eval_every": eval_every, "run.eval_episodes": 2, "ddpg.hidden": "16,16",
        "ddpg.batch_size": 16, "run.train_steps": 5, "meta.hidden": "16,16",
        "meta.explore_steps": 50, "meta.eval_steps": 100, "meta.visit_samples": 64,
        "run.rollout_steps": 50, "env.episode_length": 60,
    }
    base.update(overrides)
    return make_config(env, method, steps=steps, overrides=base, physics=physics)


def fabricate_run(path, task, method, values, steps, complete=True, visit_obs=None):
    """A run folder like experiments.run writes: config.json, metrics.jsonl, (summary.json), (visits.npz)."""
    os.makedirs(path)
    kind = "meta" if method.startswith("meta") else "ddpg"
    cfg = config_lib.make_config(task, kind, steps=int(steps[-1]) if complete else 3 * int(steps[-1]))
    run_args = {"env": task, "method": kind, "teacher": None, "preset": "paper", "noise": None,
                "seeds": len(values), "seed": 0, "steps": None, "source": "gymnasium", "overrides": []}
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
