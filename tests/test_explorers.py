"""Explorers are plug-ins: a new one is a class and a ``register`` call; the loop imports none of them."""

import ast
import dataclasses
import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from metapg_jax import explorers
from metapg_jax.loop import TrainState, Trainer
from metapg_jax.rollout import completed_episode_mean, rollout
from metapg_jax.train import make_train, seed_keys, vmap_seeds
from tests.helpers import tiny_config

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


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


def _imports(path):
    """Every metapg_jax module a file imports, at the top or inside functions."""
    out = set()
    for node in ast.walk(ast.parse(open(path).read())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("metapg_jax"):
            out.add(node.module)
            out |= {f"{node.module}.{a.name}" for a in node.names}
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("metapg_jax")}
    return out


def test_the_package_has_no_import_cycles_and_the_loop_imports_no_explorer_or_student():
    pkg = os.path.join(ROOT, "metapg_jax")
    modules = {f"metapg_jax.{f[:-3]}": os.path.join(pkg, f) for f in os.listdir(pkg) if f.endswith(".py")
               and f != "__init__.py"}
    graph = {m: {d for d in _imports(p) if d in modules and d != m} for m, p in modules.items()}
    assert not graph["metapg_jax.loop"] & {"metapg_jax.meta", "metapg_jax.noise", "metapg_jax.teacher",
                                           "metapg_jax.explorers", "metapg_jax.train", "metapg_jax.students",
                                           "metapg_jax.ddpg", "metapg_jax.td3"}
    # Explorers use the student through its interface only (metapg_jax.students), never a student's module.
    for explorer in ("metapg_jax.meta", "metapg_jax.noise", "metapg_jax.teacher"):
        assert not graph[explorer] & {"metapg_jax.ddpg", "metapg_jax.td3", "metapg_jax.students"}, explorer

    state = {}

    def visit(m, path):
        if state.get(m) == "done":
            return
        assert state.get(m) != "open", "import cycle: " + " -> ".join(path + [m])
        state[m] = "open"
        for d in sorted(graph[m]):
            visit(d, path + [m])
        state[m] = "done"

    for m in sorted(graph):
        visit(m, [])
