"""A new explorer and a new student, each written in a file of its own, run through ``experiments.run``
by name (``--plugin FILE --method NAME --student NAME``) with no edit to the package, and resume."""

import json
import os
import sys
import textwrap

import numpy as np
import pytest

from experiments import run
from metapg_jax import config as config_lib
from metapg_jax import explorers, students

PLUGIN = textwrap.dedent('''
    """A user's file: uniformly random exploration (the explorer of tests/test_explorers.py), and a DDPG that
    counts its own updates."""
    import dataclasses

    import jax
    import jax.numpy as jnp
    from flax import struct

    from metapg_jax import explorers, students
    from metapg_jax.ddpg import DDPG
    from tests.test_explorers import UniformExplorer


    @struct.dataclass
    class CountingState:
        inner: object
        count: jax.Array

        @property
        def actor(self):
            return self.inner.actor

        @property
        def critic(self):
            return self.inner.critic


    @dataclasses.dataclass(frozen=True)
    class CountingDDPG:
        ddpg: DDPG
        obs_size: int
        action_size: int

        def init(self, key):
            return CountingState(self.ddpg.init(key), jnp.zeros((), jnp.int32))

        def normalize(self, normalizer, obs):
            return self.ddpg.normalize(normalizer, obs)

        def actor_apply(self, actor, obs_normalized):
            return self.ddpg.actor_apply(actor, obs_normalized)

        def deterministic_policy(self, actor, normalizer):
            return self.ddpg.deterministic_policy(actor, normalizer)

        def update(self, state, normalizer, batch):
            inner, metrics = self.ddpg.update(state.inner, normalizer, batch)
            count = state.count + 1
            return CountingState(inner, count), {**metrics, "own_updates": count.astype(jnp.float32)}


    explorers.register("uniform", lambda config: UniformExplorer())
    students.register("counting", lambda config, obs, act: CountingDDPG(DDPG(config.ddpg, obs, act), obs, act))
''')

TINY = ["--env=pendulum", "--seeds=2", "--quiet", "--no-plot", "--set", "run.eval_every=300",
        "--set", "ddpg.hidden=16,16", "--set", "ddpg.batch_size=16", "--set", "run.train_steps=5",
        "--set", "run.eval_episodes=2", "--set", "meta.visit_samples=16", "--set", "env.episode_length=60"]


@pytest.fixture
def clean_registries(monkeypatch):
    """Registrations made by a test do not leak into the others."""
    monkeypatch.setattr(explorers, "_FACTORIES", dict(explorers._FACTORIES))
    monkeypatch.setattr(students, "_FACTORIES", dict(students._FACTORIES))
    monkeypatch.setattr(config_lib, "_REGISTERED_METHODS", set(config_lib._REGISTERED_METHODS))
    monkeypatch.setattr(config_lib, "_REGISTERED_STUDENTS", set(config_lib._REGISTERED_STUDENTS))


def _rows(out):
    return [json.loads(line) for line in open(os.path.join(out, "metrics.jsonl"))]


@pytest.mark.usefixtures("clean_registries")
def test_a_plugin_explorer_and_student_train_through_the_cli_and_resume(tmp_path, monkeypatch):
    from metapg_jax import load_policy

    plugin = tmp_path / "my_exploration.py"
    plugin.write_text(PLUGIN)
    out = str(tmp_path / "run")
    argv = [*TINY, f"--plugin={plugin}", "--method=uniform", "--student=counting"]
    assert run.main([*argv, "--steps=600", "--out", out]) == 0
    stored = json.load(open(os.path.join(out, "config.json")))
    assert stored["config"]["student"] == "counting" and stored["config"]["run"]["method"] == "uniform"
    assert stored["run_args"]["plugins"] == [str(plugin)]
    rows = _rows(out)
    assert {r["chunk"] for r in rows} == {0, 1} and all(np.isfinite(r["eval_return"]) for r in rows)
    assert all(r["own_updates"] > 0 for r in rows)                         # the student's own metric
    assert [r["uniform_steps"] for r in rows if r["seed"] == 0][-1] > 0    # the explorer's
    act = load_policy(os.path.join(out, "policy.npz"), seed=0)             # export works for it
    assert act(np.zeros(3, np.float32)).shape == (1,)

    # A later process knows nothing of the plugin: --resume imports it again from the stored run.
    for name in [m for m in sys.modules if m.startswith("metapg_plugin_")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setattr(explorers, "_FACTORIES", {k: v for k, v in explorers._FACTORIES.items() if k != "uniform"})
    monkeypatch.setattr(students, "_FACTORIES", {k: v for k, v in students._FACTORIES.items() if k != "counting"})
    monkeypatch.setattr(config_lib, "_REGISTERED_METHODS", config_lib._REGISTERED_METHODS - {"uniform"})
    monkeypatch.setattr(config_lib, "_REGISTERED_STUDENTS", config_lib._REGISTERED_STUDENTS - {"counting"})
    assert run.main(["--quiet", "--no-plot", "--resume", out, "--steps=900"]) == 0
    rows = _rows(out)
    assert {r["chunk"] for r in rows} == {0, 1, 2} and len(rows) == 6


@pytest.mark.usefixtures("clean_registries")
def test_bad_plugins_and_unknown_names_are_refused_before_compiling(tmp_path, capsys):
    assert run.main([*TINY, "--plugin", str(tmp_path / "missing.py"), "--out", str(tmp_path / "a")]) == 2
    assert "--plugin" in capsys.readouterr().err
    assert run.main([*TINY, "--plugin", "no_such_module_here", "--out", str(tmp_path / "b")]) == 2
    assert "cannot import it" in capsys.readouterr().err
    broken = tmp_path / "broken.py"
    broken.write_text("raise RuntimeError('typo')\n")
    assert run.main([*TINY, "--plugin", str(broken), "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert "importing it failed: RuntimeError: typo" in err and len(err.strip().splitlines()) == 1
    plugin = tmp_path / "mine.py"
    plugin.write_text(PLUGIN)
    assert run.main([*TINY, "--plugin", str(plugin), "--student=sac", "--out", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err
    assert "unknown student 'sac'; valid students: ddpg, td3, counting" in err
    assert not os.path.exists(tmp_path / "d")
