"""A new explorer and a new student, each written in a file of its own, run through ``experiments.run``
by name (``--plugin FILE --method NAME --student NAME``) with no edit to the package, and resume."""

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from experiments import run
from tests.helpers import ROOT, isolated_registry, tiny_argv

PLUGIN = textwrap.dedent('''
    """A user's file: uniformly random exploration with its own config group (the action scale and the cycle
    length), schedule and metric, and a DDPG that counts its own updates."""
    import dataclasses

    import jax
    import jax.numpy as jnp
    from flax import struct

    from metapg_jax import strategy
    from metapg_jax.rollout import rollout
    from metapg_jax.strategies.ddpg import DDPG


    @dataclasses.dataclass(frozen=True)
    class UniformConfig:
        scale: float = 1.0       # actions ~ U(-scale, scale)
        cycle_steps: int = 50    # env steps per cycle


    @dataclasses.dataclass(frozen=True)
    class UniformExplorer(strategy.Explorer):
        cfg: UniformConfig

        def init(self, trainer, student, key):
            return {"steps": jnp.zeros((), jnp.int32)}

        def cycle(self, trainer, state):
            key, k_roll, k_train = jax.random.split(state.key, 3)
            policy = lambda carry, obs, first, k: (self.cfg.scale * trainer.random_action(k), carry, None)
            env_state, _, data, _, _ = rollout(trainer.env, policy, state.env_state, None, k_roll, self.cfg.cycle_steps)
            state = trainer.store(state.replace(env_state=env_state, key=key), data)
            state, metrics = trainer.student_updates(state, k_train, trainer.config.run.train_steps)
            steps = state.explorer["steps"] + data.reward.shape[0]
            return state.replace(explorer={"steps": steps}), {
                **metrics, "uniform_steps": steps, "largest_action": jnp.max(jnp.abs(data.action))}


    def _validate(config):
        if config.run.method == "uniform" and not config.uniform.scale > 0:
            raise ValueError(f"uniform.scale must be positive, got {config.uniform.scale}")


    strategy.register_explorer(
        "uniform", lambda config: UniformExplorer(config.uniform), group=UniformConfig, validate=_validate,
        steps_per_cycle=lambda config: config.uniform.cycle_steps, cycle_metrics=("largest_action",),
        cycle_panels=(("largest_action", "largest |action|"),), label=lambda config: f"x{config.uniform.scale}",
        flag=("scale", "scale"))


    @struct.dataclass
    class CountingState:
        inner: object
        count: jax.Array

        @property
        def actor(self):
            return self.inner.actor


    @dataclasses.dataclass(frozen=True)
    class CountingDDPG(strategy.Student):
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

        def guarded_params(self, state):  # the NaN guard's (default: the actor alone)
            return self.ddpg.guarded_params(state.inner)


    strategy.register_student("counting", lambda config, obs, act: CountingDDPG(DDPG(config.ddpg, obs, act), obs, act))
''')

TINY = tiny_argv(method=None)


@pytest.fixture
def clean_registries(monkeypatch):
    """Registrations made by a test do not leak into the others."""
    isolated_registry(monkeypatch)


def _rows(out, name="metrics.jsonl"):
    return [json.loads(line) for line in open(os.path.join(out, name))]


@pytest.mark.slow
@pytest.mark.usefixtures("clean_registries")
def test_a_plugin_explorer_and_student_train_through_the_cli_and_resume(tmp_path):
    from metapg_jax import load_policy

    plugin = tmp_path / "my_exploration.py"  # outside the package
    plugin.write_text(PLUGIN)
    out = str(tmp_path / "run")
    argv = [*TINY, f"--plugin={plugin}", "--method=uniform", "--student=counting", "--checkpoint-every=1",
            "--set", "uniform.cycle_steps=30", "--scale=0.5"]  # its shortcut: an option once --plugin imports it
    assert run.main([*argv, "--set", "uniform.scale=-1", "--out", str(tmp_path / "bad")]) == 2  # its own check
    assert not os.path.exists(tmp_path / "bad")
    assert run.main([*argv, "--steps=600", "--out", out]) == 0
    stored = json.load(open(os.path.join(out, "config.json")))
    assert stored["config"]["student"] == "counting" and stored["config"]["run"]["method"] == "uniform"
    assert stored["config"]["uniform"] == {"scale": 0.5, "cycle_steps": 30}  # its group, with the override
    assert stored["run_args"]["plugins"] == [str(plugin)] and stored["run_args"]["scale"] == "0.5"
    rows = _rows(out)
    assert {r["chunk"] for r in rows} == {0, 1} and all(np.isfinite(r["eval_return"]) for r in rows)
    assert all(r["own_updates"] > 0 for r in rows)                         # the student's own metric
    # The explorer's: steps after each of a chunk's ten 30-step cycles, as the chunk's mean (30, 60, ... 300: 165).
    assert [r["uniform_steps"] for r in rows if r["seed"] == 0] == [165, 465]
    cycles = _rows(out, "cycles.jsonl")  # its per-cycle metric: 10 cycles per chunk
    assert len(cycles) == 2 * 20 and all(0 < c["largest_action"] <= 0.5 for c in cycles)
    act = load_policy(os.path.join(out, "policy.npz"), seed=0)             # export works for it
    assert act(np.zeros(3, np.float32)).shape == (1,)

    # A fresh process knows nothing of the plugin: --resume imports it again from the stored run, with its
    # group's stored values.
    res = subprocess.run([sys.executable, "-m", "experiments.run", "--quiet", "--no-plot", "--resume", out,
                          "--steps=900"], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    rows = _rows(out)
    assert {r["chunk"] for r in rows} == {0, 1, 2} and len(rows) == 6
    assert [r["uniform_steps"] for r in rows if r["seed"] == 0] == [165, 465, 765]
    assert json.load(open(os.path.join(out, "config.json")))["config"]["uniform"]["scale"] == 0.5


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
    assert run.main([*TINY, "--plugin", str(plugin), "--student=redq", "--out", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err
    assert "unknown student 'redq'; valid students: counting, ddpg, sac, td3" in err
    assert not os.path.exists(tmp_path / "d")
    misspelt = tmp_path / "misspelt.py"  # an explorer whose metrics hook is misspelt
    misspelt.write_text(PLUGIN.replace("class UniformExplorer(strategy.Explorer):",
                                       "class UniformExplorer(strategy.Explorer):\n    def metric(self, carry):\n"
                                       "        return {}\n"))
    assert run.main([*TINY, "--plugin", str(misspelt), "--method=uniform", "--out", str(tmp_path / "e")]) == 2
    err = capsys.readouterr().err
    assert "explorer UniformExplorer: 'metric' is not a hook of strategy.Explorer (did you mean 'metrics'?)" in err
    assert len(err.strip().splitlines()) == 1 and not os.path.exists(tmp_path / "e")
