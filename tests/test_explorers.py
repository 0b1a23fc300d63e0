"""Explorers are plug-ins: a new one is a class and a ``register`` call (the import graph: tests/test_imports.py)."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from metapg_jax import explorers
from metapg_jax.loop import TrainState, Trainer
from metapg_jax.rollout import completed_episode_mean, rollout
from metapg_jax.train import make_train, seed_keys, vmap_seeds
from tests.helpers import tiny_config


class UniformExplorer:
    """Uniformly random actions forever (an explorer a user might write: one class, no loop edits)."""

    def init(self, trainer: Trainer, student, key):
        return {"steps": jnp.zeros((), jnp.int32)}

    def cycle(self, trainer: Trainer, state: TrainState):
        key, k_roll, k_train = jax.random.split(state.key, 3)
        policy = lambda carry, obs, first, k: (trainer.random_action(k), carry, None)
        env_state, _, transitions, stats, _ = rollout(trainer.env, policy, state.env_state, None, k_roll,
                                                      trainer.config.run.rollout_steps)
        state = trainer.store(state.replace(env_state=env_state, key=key), transitions)
        state, metrics = trainer.student_updates(state, k_train, trainer.config.run.train_steps)
        steps = state.explorer["steps"] + transitions.reward.shape[0]
        return state.replace(explorer={"steps": steps}), {
            **metrics, "train_return": completed_episode_mean(stats)[0], "uniform_steps": steps}


def test_a_registered_explorer_trains_without_touching_the_loop(monkeypatch):
    from metapg_jax import config as config_lib

    monkeypatch.setattr(explorers, "_FACTORIES", dict(explorers._FACTORIES))  # no registration leaks out
    monkeypatch.setattr(config_lib, "_REGISTERED_METHODS", set(config_lib._REGISTERED_METHODS))
    explorers.register("uniform", lambda config: UniformExplorer())
    cfg = tiny_config("uniform")  # make_config takes a registered method; the baseline's schedule
    assert cfg.run.method == "uniform" and cfg.steps_per_cycle == cfg.run.rollout_steps
    trainer = make_train(cfg)
    assert isinstance(trainer.explorer, UniformExplorer)
    state = jax.jit(vmap_seeds(trainer.init))(seed_keys(0, 2))
    state, metrics = jax.jit(vmap_seeds(trainer.train_chunk))(state)
    assert np.all(np.asarray(state.explorer["steps"]) == cfg.run.eval_every)
    assert np.all(np.asarray(state.env_steps) == cfg.run.eval_every)
    assert np.all(np.asarray(metrics["cycle"]["finite"]))
    assert np.all(np.isfinite(np.asarray(metrics["eval_return"])))


def test_an_unknown_method_is_refused_naming_the_registered_ones():
    cfg = tiny_config("ddpg")
    with pytest.raises(ValueError, match="ddpg, meta"):
        explorers.make(dataclasses.replace(cfg, run=dataclasses.replace(cfg.run, method="nope")))
