"""``make_train(config, env)``: the whole training run as pure, jittable functions.

Builds the student (``config.student``: ``metapg_jax.ddpg.DDPG`` or ``metapg_jax.td3.TD3``) and the explorer of ``config.run.method``
(``metapg_jax.explorers``) and returns a ``metapg_jax.loop.Trainer``: ``init(key)``, ``train_chunk(state)``
(one evaluation interval) and ``train(key)`` (the whole run as one program). Seeds are a vmap over keys
(``seed_keys``; ``vmap_seeds`` names the seed axis):

    trainer = make_train(make_config("pendulum", method="meta"))
    state, metrics = jax.jit(jax.vmap(trainer.train))(seed_keys(0, 8))
"""

from __future__ import annotations

from brax.envs.base import Env

from metapg_jax import explorers
from metapg_jax.config import Config, validate
from metapg_jax.ddpg import DDPG
from metapg_jax.loop import Trainer, seed_keys, vmap_seeds
from metapg_jax.td3 import TD3

__all__ = ["make_train", "seed_keys", "vmap_seeds"]


def make_train(config: Config, env: Env | None = None) -> Trainer:
    """Validates ``config`` and builds the trainer (``env`` defaults to ``envs.make`` of the config)."""
    import envs

    validate(config)
    if env is None:
        env = envs.make(config.env.name, source=config.env.source, episode_length=config.episode_length,
                        physics=config.env.physics)
    obs_size, action_size = int(env.observation_size), int(env.action_size)
    if config.student == "td3":
        student = TD3(config.ddpg, obs_size, action_size, td3=config.td3)
    else:
        student = DDPG(config.ddpg, obs_size, action_size)
    return Trainer(config, env, student, explorers.make(config))
