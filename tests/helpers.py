"""Tiny configurations for fast tests (pendulum, small networks, short chunks)."""

from metapg_jax.config import make_config


def tiny_config(method="ddpg", steps=600, eval_every=300, **overrides):
    base = {
        "run.eval_every": eval_every, "run.eval_episodes": 2, "ddpg.hidden": "16,16",
        "ddpg.batch_size": 16, "run.train_steps": 5, "meta.hidden": "16,16",
        "meta.explore_steps": 50, "meta.eval_steps": 100, "meta.visit_samples": 64,
        "run.rollout_steps": 50, "env.episode_length": 60,
    }
    base.update(overrides)
    return make_config("pendulum", method, steps=steps, overrides=base)
