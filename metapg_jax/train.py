"""``make_train(config, env)``: the whole training run as pure, jittable functions.

Builds the student of ``config.student`` and the explorer of ``config.run.method`` (registered in
``metapg_jax.strategy``: the built-in ones or a plug-in's) and returns a ``metapg_jax.loop.Trainer``: ``init(key)``, ``train_chunk(state)`` (one
evaluation interval) and ``train(key)`` (the whole run as one program). Seeds are a vmap over keys
(``seed_keys``; ``vmap_seeds`` names the seed axis):

    trainer = make_train(make_config(method="meta", student="td3"))   # the default task
    state, metrics = jax.jit(jax.vmap(trainer.train))(seed_keys(0, 8))
"""

from __future__ import annotations

import dataclasses
from typing import Any

from brax.envs.base import Env

from metapg_jax import strategy
from metapg_jax.config import Config, validate
from metapg_jax.loop import Trainer
from metapg_jax.seeds import seed_keys, vmap_seeds

__all__ = ["make_train", "seed_keys", "vmap_seeds"]


def make_train(config: Config, env: Env | None = None, *, student: str | Any | None = None,
               explorer: str | Any | None = None) -> Trainer:
    """Validates ``config`` and builds the trainer (``env`` defaults to ``envs.make`` of the config).

    ``student`` and ``explorer`` name a registered student or explorer (replacing ``config.student`` /
    ``config.run.method``, so that checkpoints and labels say what ran; the schedule stays the config's:
    ``make_config(..., method=, student=)`` derives a method's schedule, e.g. Meta's, from the task), or
    are an object implementing the interface (used as is; the config's names are kept)."""
    import envs

    if isinstance(student, str):
        config = dataclasses.replace(config, student=student)
    if isinstance(explorer, str):
        config = dataclasses.replace(config, run=dataclasses.replace(config.run, method=explorer))
    validate(config)
    if env is None:
        env = envs.make(config.env.name, source=config.env.source, episode_length=config.episode_length,
                        physics=config.env.physics)
    obs_size, action_size = int(env.observation_size), int(env.action_size)
    if student is None or isinstance(student, str):
        student = strategy.student(config.student).make(config, obs_size, action_size)
    if explorer is None or isinstance(explorer, str):
        explorer = strategy.explorer(config.run.method).make(config)
    return Trainer(config, env, student, explorer)
