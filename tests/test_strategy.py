"""The plug-in contract (metapg_jax/strategy.py): one registry per kind, a strategy's own config group, and no
strategy named outside its own file (the import graph: tests/test_imports.py)."""

import ast
import dataclasses
import os
import re
import types

import jax
import numpy as np
import pytest

from metapg_jax import config as config_lib
from metapg_jax import strategy
from metapg_jax.train import make_train, seed_keys, vmap_seeds
from tests.helpers import UniformExplorer, isolated_registry, tiny_config

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_a_registered_explorer_trains_without_touching_the_loop(monkeypatch):
    isolated_registry(monkeypatch)
    strategy.register_explorer("uniform", lambda config: UniformExplorer())
    cfg = tiny_config("uniform")  # make_config takes a registered method; run.rollout_steps per cycle
    assert cfg.run.method == "uniform" and cfg.steps_per_cycle == cfg.run.rollout_steps
    trainer = make_train(cfg)
    assert isinstance(trainer.explorer, UniformExplorer)
    state = jax.jit(vmap_seeds(trainer.init))(seed_keys(0, 2))
    state, metrics = jax.jit(vmap_seeds(trainer.train_chunk))(state)
    assert np.all(np.asarray(state.explorer["steps"]) == cfg.run.eval_every)
    assert np.all(np.asarray(state.env_steps) == cfg.run.eval_every)
    assert np.all(np.asarray(metrics["cycle"]["finite"]))
    assert np.all(np.isfinite(np.asarray(metrics["eval_return"])))


def test_an_unknown_method_or_student_is_refused_naming_the_registered_ones():
    cfg = tiny_config("ddpg")
    with pytest.raises(ValueError, match=r"unknown method 'nope'; valid methods: ddpg, meta, own, random$"):
        make_train(dataclasses.replace(cfg, run=dataclasses.replace(cfg.run, method="nope")))
    with pytest.raises(ValueError, match=r"unknown student 'nope'; valid students: ddpg, sac, td3$"):
        config_lib.make_config("pendulum", student="nope")


class _Plain(strategy.ActingExplorer):
    """An explorer with the required hooks alone: uniformly random actions."""

    def init(self, trainer, student, key):
        return ()

    def act(self, trainer, carry, student, normalizer, obs, key):
        return trainer.random_action(key), carry


class _Starting(_Plain):
    def episode_start(self, trainer, carry, student, key):
        return carry


def test_the_loop_asks_no_hook_whether_it_is_there():
    with open(os.path.join(ROOT, "metapg_jax", "loop.py")) as f:
        source = f.read()
    assert "hasattr(" not in source and "getattr(" not in source


def test_a_plain_explorer_inherits_hooks_that_do_nothing_and_the_loop_leaves_their_work_out():
    explorer, carry = _Plain(), {"x": np.zeros(2)}
    assert explorer.episode_start(None, carry, None, None) is carry
    assert explorer.adapt(None, carry, None, None, None, None) is carry
    assert explorer.adapt_every == 0 and explorer.metrics(carry) == {} and explorer.guarded_params(carry) == ()
    trainer = types.SimpleNamespace(acting_cycle=lambda state: ("the loop's", state))
    assert explorer.cycle(trainer, "state") == ("the loop's", "state")  # an acting explorer's cycle is the loop's

    def conds(explorer):
        trainer = make_train(tiny_config("ddpg"), explorer=explorer)
        state = jax.eval_shape(vmap_seeds(trainer.init), seed_keys(0, 2))
        return str(jax.make_jaxpr(vmap_seeds(trainer.train_chunk))(state)).count("cond[")

    # The default episode start is not traced at all; one of the explorer's own is, under a conditional.
    assert conds(_Starting()) > conds(_Plain())


def test_a_student_guards_its_actor_by_default():
    class Minimal(strategy.Student):
        pass

    state = type("State", (), {"actor": {"w": np.ones(2)}, "critic": {"w": np.ones(2)}})()
    assert Minimal().guarded_params(state) is state.actor
    with pytest.raises(NotImplementedError, match="Minimal is deterministic: it has no sample_action"):
        Minimal().sample_action(None, None, None)


class _OwnCycle(strategy.Explorer):
    def init(self, trainer, student, key):
        return ()

    def cycle(self, trainer, state):
        return state, {}


class _Unrelated:
    """The hooks of an acting explorer, without its base."""

    def init(self, trainer, student, key):
        return ()

    def act(self, trainer, carry, student, normalizer, obs, key):
        return trainer.random_action(key), carry


def _mine(base: type, **hooks) -> type:
    return type("Mine", (base,), hooks)


_ANY = lambda self, *args: None


@pytest.mark.parametrize("hooks, error", [
    ({"episode_starts": _ANY},
     "'episode_starts' is not a hook of strategy.ActingExplorer (did you mean 'episode_start'?)"),
    ({"metric": _ANY}, "'metric' is not a hook of strategy.ActingExplorer (did you mean 'metrics'?)"),
    ({"adapt_evry": 5}, "'adapt_evry' is not a hook of strategy.ActingExplorer (did you mean 'adapt_every'?)"),
])
def test_a_misspelt_hook_is_refused_when_registered_or_built_naming_the_closest(hooks, error, monkeypatch):
    isolated_registry(monkeypatch)
    mine, error = _mine(_Plain, **hooks), f"^explorer Mine: {re.escape(error)}$"
    with pytest.raises(ValueError, match=error):
        strategy.register_explorer("mine", mine)  # a class as ``make``: checked at registration
    strategy.register_explorer("mine", lambda config: mine())
    with pytest.raises(ValueError, match=error):
        make_train(tiny_config("mine"))  # any other ``make``: when the trainer is built
    with pytest.raises(ValueError, match=error):
        make_train(tiny_config("ddpg"), explorer=mine())  # an object passed as is
    strategy.check_explorer(_mine(_Plain, _episode_starts=_ANY, actor=_ANY))  # private and distant names pass


def test_a_strategy_outside_the_contract_is_refused_before_compiling():
    cfg = tiny_config("ddpg")
    refused = [
        (_Unrelated(), "explorer _Unrelated derives from neither strategy.ActingExplorer (it chooses actions) nor "
                       "strategy.Explorer (a cycle of its own)"),
        (_mine(strategy.ActingExplorer, init=_ANY)(),
         "explorer Mine lacks act (required of a strategy.ActingExplorer)"),
        (_mine(strategy.Explorer, init=_ANY)(), "explorer Mine lacks cycle (required of a strategy.Explorer)"),
        (_mine(_Plain, cycle=_ANY)(), "explorer Mine defines cycle: an ActingExplorer's cycle is the loop's, an "
                                      "explorer with a cycle of its own derives from strategy.Explorer"),
        (_mine(_OwnCycle, metrics=_ANY)(), "explorer Mine defines metrics, a hook of strategy.ActingExplorer that "
                                           "nothing runs for a strategy.Explorer (a cycle of its own)"),
    ]
    for explorer, error in refused:
        with pytest.raises(ValueError, match=f"^{re.escape(error)}$"):
            make_train(cfg, explorer=explorer)
    ddpg = make_train(cfg).student
    refused = [
        (_Unrelated(), "student _Unrelated does not derive from strategy.Student"),
        (_mine(strategy.Student, init=_ANY)(), "student Mine lacks obs_size, action_size, normalize, actor_apply, "
                                               "deterministic_policy, update (required of a strategy.Student)"),
        (_mine(type(ddpg), normalise=_ANY)(ddpg.cfg, ddpg.obs_size, ddpg.action_size),
         "student Mine: 'normalise' is not a hook of strategy.Student (did you mean 'normalize'?)"),
    ]
    for student, error in refused:
        with pytest.raises(ValueError, match=f"^{re.escape(error)}$"):
            make_train(cfg, student=student)

@dataclasses.dataclass(frozen=True)
class _Knobs:
    width: float = 0.5
    steps: int = 60


def test_a_strategy_group_is_typed_overridable_stored_and_read_back(monkeypatch):
    isolated_registry(monkeypatch)
    strategy.register_explorer("knobbed", lambda config: UniformExplorer(), group=_Knobs,
                               group_defaults=lambda config: _Knobs(steps=30 if config.env.name == "pendulum" else 60),
                               steps_per_cycle=lambda config: config.knobbed.steps)
    cfg = config_lib.make_config("pendulum", "knobbed", overrides={"knobbed.width": "0.25"})
    assert cfg.knobbed == _Knobs(width=0.25, steps=30) and cfg.steps_per_cycle == 30
    assert cfg.meta.explore_steps == 100  # the other strategies' groups are all there
    stored = config_lib.to_dict(cfg)
    assert stored["knobbed"] == {"width": 0.25, "steps": 30}
    assert config_lib.from_dict(stored) == cfg
    with pytest.raises(ValueError, match="knobbed.width: expected float"):
        config_lib.make_config("pendulum", "knobbed", overrides={"knobbed.width": "wide"})
    with pytest.raises(ValueError, match="fields of knobbed: width, steps"):
        config_lib.make_config("pendulum", "knobbed", overrides={"knobbed.depth": "1"})
    for taken in ("run", "meta", "replace"):  # a core group, another strategy's, a config method
        with pytest.raises(ValueError, match=f"config group '{taken}'"):
            strategy.register_explorer("other", lambda config: UniformExplorer(), group=_Knobs, group_name=taken)


def test_a_stored_group_nobody_declares_is_refused_and_moved_fields_are_read_in_their_new_place():
    stored = config_lib.to_dict(config_lib.make_config("pendulum", "meta"))
    with pytest.raises(ValueError, match="group 'knobbed' that no registered strategy declares"):
        config_lib.from_dict({**stored, "knobbed": {"width": 1.0}})
    old = {**stored, "run": {k: v for k, v in stored["run"].items() if k != "visit_samples"},
           "meta": {**stored["meta"], "visit_samples": 16}}  # a config.json written before the field moved
    assert config_lib.from_dict(old).run.visit_samples == 16
    assert config_lib.make_config("pendulum", overrides={"meta.visit_samples": 16}).run.visit_samples == 16


# The modules that run every strategy alike: the pure library's core, the host side, the env registry and the
# generic commands. The strategies' own files, and the experiments about one of them (the teacher's screen and
# ablation, Table 2's grid, the benchmarks), name them by design.
GENERIC = ["metapg_jax/config/__init__.py", "metapg_jax/config/schema.py", "metapg_jax/config/fields.py",
           "metapg_jax/config/build.py", "metapg_jax/loop.py", "metapg_jax/train.py", "metapg_jax/sweep.py",
           "metapg_jax/seeds.py", "metapg_jax/strategy.py", "metapg_jax/actor_critic.py", "metapg_jax/rollout.py",
           "metapg_jax/evaluate.py", "metapg_jax/replay.py", "metapg_jax/visits.py", "envs/__init__.py",
           "experiments/run.py", "experiments/sweep.py", "experiments/export.py", "experiments/training/args.py",
           "experiments/training/memory.py", "experiments/training/finish.py", "experiments/training/grid_cells.py",
           *(f"metapg_jax/host/{f}" for f in sorted(os.listdir(os.path.join(ROOT, "metapg_jax", "host")))
             if f.endswith(".py"))]


def _names_in(path: str, names: set[str], groups: set[str]) -> list[str]:
    """Where a file branches on a strategy's name, reads a strategy's group, or imports a strategy's module."""
    found = []
    for node in ast.walk(ast.parse(open(path).read())):
        if isinstance(node, ast.Compare):
            for side in [node.left, *node.comparators]:
                items = side.elts if isinstance(side, (ast.Tuple, ast.List, ast.Set)) else [side]
                found += [f"l.{node.lineno}: compares with {c.value!r}" for c in items
                          if isinstance(c, ast.Constant) and c.value in names]
        elif isinstance(node, ast.Attribute) and node.attr in groups and ast.unparse(node.value).endswith(
                ("cfg", "config")):  # a config's group (not, say, a checkpoint's ``meta`` item)
            found.append(f"l.{node.lineno}: .{node.attr}")
        elif isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant) and node.slice.value in groups:
            found.append(f"l.{node.lineno}: [{node.slice.value!r}]")
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("metapg_jax.strategies"):
            found.append(f"l.{node.lineno}: imports {node.module}")
    return found


def test_no_generic_module_names_a_registered_strategy():
    names = {*strategy.explorers(), *strategy.students()}
    groups = set(strategy.groups())
    assert {"ddpg", "meta", "td3"} <= names and {"meta", "noise", "td3"} <= groups  # the check has teeth:
    assert _names_in(os.path.join(ROOT, "metapg_jax", "strategies", "meta.py"), names, groups)  # it sees meta's own
    found = {path: _names_in(os.path.join(ROOT, path), names, groups) for path in GENERIC}
    assert {path: where for path, where in found.items() if where} == {}


def test_the_reserved_group_names_are_the_configs_own_names():
    """strategy.RESERVED (a group may not take these) is written out because config imports strategy, not the
    other way round; it must stay every field and public attribute of Config."""
    names = {n for n in dir(config_lib.Config) if not n.startswith("_")}
    assert strategy.RESERVED == names | {f.name for f in dataclasses.fields(config_lib.Config)}


def test_the_random_explorer_ignores_the_policy_and_draws_uniform_actions():
    """``--method=random`` (metapg_jax/strategies/random_actions.py): the same key gives the same action whatever
    the student's parameters, and the actions fill [-1, 1]^d uniformly (while the student trains: its golden
    case, tests/golden.py)."""
    trainer = make_train(tiny_config("random"))
    one, two = (trainer.student.init(jax.random.PRNGKey(k)) for k in (0, 1))
    keys = jax.random.split(jax.random.PRNGKey(3), 4000)
    obs = np.zeros(trainer.env.observation_size, np.float32)

    def actions(student):
        return jax.vmap(lambda k: trainer.explorer.act(trainer, (), student, None, obs, k)[0])(keys)

    a = np.asarray(actions(one))
    np.testing.assert_array_equal(a, np.asarray(actions(two)))
    assert a.shape == (4000, trainer.env.action_size) and a.min() >= -1.0 and a.max() <= 1.0
    assert abs(a.mean()) < 0.05 and abs(a.var() - 1 / 3) < 0.03   # U(-1, 1): mean 0, variance 1/3
