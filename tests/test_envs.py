"""Registry (a task is one spec), wrappers (time limit, auto-reset, flags, statistics) and the JAX Pendulum."""

import dataclasses
import os
import re

import gymnasium
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from brax.envs.base import Env, State

import envs
from envs.pendulum import Pendulum
from envs.wrappers import AutoResetWrapper, EpisodeWrapper

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_unknown_task_lists_valid_names():
    with pytest.raises(ValueError, match="valid tasks: pendulum, inverted_pendulum"):
        envs.make("cartpole")
    with pytest.raises(ValueError, match="valid sources"):
        envs.make("hopper", source="dm_control")


def test_a_task_added_to_the_registry_alone_gets_its_schedule_budget_and_name_from_its_spec(monkeypatch):
    """One spec in ``envs.TASKS`` is the whole task: the config, Meta's schedule, the tables' name and the engine
    choice read it; no other module lists it."""
    from experiments.grid import methods as grid
    from metapg_jax.host.driver import physics_label
    from metapg_jax.config import make_config, validate

    spec = dataclasses.replace(envs.TASKS["pendulum"], paper_budget=60_000, eval_every=6_000, display_name="Toy",
                               meta_schedule=envs.MetaSchedule(200, 400, 100, 2), table2=None)
    monkeypatch.setitem(envs.TASKS, "toy", spec)
    meta = validate(make_config("toy", "meta"))
    assert (meta.meta.explore_steps, meta.meta.eval_steps, meta.run.train_steps, meta.meta.teacher_steps) == \
        (200, 400, 100, 2)
    assert (meta.run.total_steps, meta.run.eval_every, meta.env.physics) == (60_000, 6_000, "mjx")
    ddpg = validate(make_config("toy", "ddpg"))
    assert (ddpg.run.total_steps, ddpg.run.eval_every, ddpg.run.train_steps) == (60_000, 6_000, 50)
    assert envs.display_name("toy") == grid.task_name("toy") == "Toy"
    assert not envs.has_mujoco("toy") and physics_label(meta) == "JAX"
    assert "toy" not in grid.tasks()  # the paper's grid: the tasks with a Table 2 row
    env = envs.make("toy")
    assert (env.observation_size, env.action_size) == (3, 1)
    # Without a schedule of its own, Algorithm 1's defaults; a MuJoCo task's constructors are its spec's.
    monkeypatch.setitem(envs.TASKS, "toy", dataclasses.replace(spec, meta_schedule=None))
    meta = make_config("toy", "meta")
    assert (meta.meta.explore_steps, meta.meta.eval_steps, meta.run.train_steps, meta.meta.teacher_steps) == \
        (100, 200, 50, 1)
    monkeypatch.setitem(envs.TASKS, "toy_hopper", dataclasses.replace(envs.TASKS["hopper"], display_name="ToyHopper"))
    assert envs.constructor("toy_hopper") is envs.constructor("hopper")
    assert envs.constructor("toy_hopper", "brax").__name__ == "brax_hopper"
    assert envs.has_mujoco("toy_hopper") and envs.resolve_physics("toy_hopper", "gymnasium", "auto", "cpu") == "mujoco"
    with pytest.raises(ValueError, match="toy has only the gymnasium source"):
        envs.constructor("toy", "brax")


def test_the_paper_tasks_are_table_2s_rows_in_its_order():
    assert envs.paper_tasks() == ("inverted_double_pendulum", "inverted_pendulum", "hopper", "pendulum", "halfcheetah",
                                  "reacher")
    assert [envs.display_name(t) for t in envs.paper_tasks()] == [
        "InvertedDoublePendulum", "InvertedPendulum", "Hopper", "Pendulum", "HalfCheetah", "Reacher"]
    assert envs.display_name("gym:Ant-v5(ctrl_cost_weight=0.1)") == "Ant-v5(ctrl_cost_weight=0.1)"


def test_the_library_names_no_built_in_task():
    """No file under metapg_jax/ names a built-in task, by its name or its display name, anywhere (code, strings,
    comments, docstrings): what a task needs is in its spec, which the library reads (``envs.DEFAULT_TASK`` is the
    default task)."""
    names = sorted({n for name, spec in envs.TASKS.items() for n in (name, spec.display_name)}, key=len, reverse=True)
    pattern = re.compile(r"(?<![A-Za-z0-9_])(" + "|".join(map(re.escape, names)) + r")(?![A-Za-z0-9_])", re.IGNORECASE)
    assert pattern.search(open(envs.__file__).read())  # the check sees a name where one is
    found = {}
    for folder, dirs, files in os.walk(os.path.join(ROOT, "metapg_jax")):
        dirs[:] = [d for d in dirs if d != "__pycache__"]
        for f in (f for f in files if f.endswith(".py")):
            path = os.path.join(folder, f)
            hits = sorted({m.group(0) for m in pattern.finditer(open(path).read())})
            if hits:
                found[os.path.relpath(path, ROOT)] = hits
    assert found == {}


def test_pendulum_step_matches_hand_computation():
    env = Pendulum()
    s = env.state_from_q(0.5, -0.3)
    s2 = env.step(s, jnp.array([0.25]))
    u = 0.25 * 2.0
    cost = 0.5**2 + 0.1 * 0.3**2 + 0.001 * u**2
    thdot = -0.3 + (3 * 10.0 / 2 * np.sin(0.5) + 3.0 * u) * 0.05
    th = 0.5 + thdot * 0.05
    np.testing.assert_allclose(s2.reward, -cost, rtol=1e-6)
    np.testing.assert_allclose(s2.obs, [np.cos(th), np.sin(th), thdot], rtol=1e-6)
    # Angle normalisation in the cost and the speed clip.
    s3 = env.step(env.state_from_q(5 * np.pi / 2, 7.9), jnp.array([1.0]))
    np.testing.assert_allclose(s3.reward, -((np.pi / 2) ** 2 + 0.1 * 7.9**2 + 0.001 * 4.0), rtol=1e-5)
    assert float(s3.obs[2]) == pytest.approx(8.0)


def test_pendulum_matches_gymnasium_over_an_episode_prefix():
    genv = gymnasium.make("Pendulum-v1").unwrapped
    genv.reset(seed=3)
    th, thdot = genv.state
    env = Pendulum()
    s = env.state_from_q(th, thdot)
    rng = np.random.default_rng(0)
    step = jax.jit(env.step)
    for _ in range(30):
        a = rng.uniform(-1, 1, size=(1,)).astype(np.float32)
        gobs, grew, term, trunc, _ = genv.step(a * 2.0)
        s = step(s, jnp.asarray(a))
        np.testing.assert_allclose(s.obs, gobs, rtol=1e-4, atol=1e-4)
        np.testing.assert_allclose(s.reward, grew, rtol=1e-4, atol=1e-4)
        assert not term


def test_wrapped_pendulum_shapes_and_finiteness_under_jit_vmap():
    env = envs.make("pendulum")
    keys = jax.random.split(jax.random.PRNGKey(0), 5)
    s = jax.jit(jax.vmap(env.reset))(keys)
    step = jax.jit(jax.vmap(env.step))
    for _ in range(10):
        s = step(s, jnp.zeros((5, 1)))
    assert s.obs.shape == (5, 3) and s.obs.dtype == jnp.float32
    assert s.reward.shape == (5,)
    assert np.isfinite(np.asarray(s.obs)).all()
    # Different keys, different initial states.
    assert len({tuple(np.round(o, 5)) for o in np.asarray(jax.vmap(env.reset)(keys).obs)}) == 5


class _Terminating(Env):
    """A 1-D toy env: x += a; terminates when x > 1. Used to check the flags."""

    def reset(self, rng):
        z = jnp.zeros((), jnp.float32)
        return State(pipeline_state=jnp.zeros(1), obs=jnp.zeros(1) + jax.random.uniform(rng, (1,)) * 0.01,
                     reward=z, done=z)

    def step(self, state, action):
        x = state.obs + action
        return state.replace(obs=x, reward=jnp.sum(x), done=(x[0] > 1.0).astype(jnp.float32))

    @property
    def observation_size(self):
        return 1

    @property
    def action_size(self):
        return 1

    @property
    def backend(self):
        return "jax"


def test_time_limit_truncates_and_autoreset_keeps_final_observation():
    env = AutoResetWrapper(EpisodeWrapper(Pendulum(), episode_length=3))
    s = env.reset(jax.random.PRNGKey(1))
    raw = Pendulum()
    q = s.pipeline_state
    for t in range(3):
        q_state = raw.step(State(q, raw._obs(q), jnp.zeros(()), jnp.zeros(())), jnp.array([0.1]))
        q = q_state.pipeline_state
        s = env.step(s, jnp.array([0.1]))
    assert float(s.info["truncated"]) == 1.0 and float(s.info["terminated"]) == 0.0
    assert float(s.done) == 1.0
    # next_obs is the true final observation; obs is already the new episode's first.
    np.testing.assert_allclose(s.info["next_obs"], q_state.obs, rtol=1e-6)
    assert not np.allclose(s.obs, s.info["next_obs"])
    assert int(s.info["steps"]) == 0 and int(s.info["episode_length"]) == 3
    assert float(s.info["running_return"]) == 0.0 and float(s.info["episode_return"]) != 0.0


def test_termination_is_not_truncation():
    env = AutoResetWrapper(EpisodeWrapper(_Terminating(), episode_length=100))
    s = env.reset(jax.random.PRNGKey(0))
    flags = []
    for _ in range(3):
        s = env.step(s, jnp.array([0.6]))
        flags.append((float(s.info["terminated"]), float(s.info["truncated"]), float(s.done)))
    assert flags[0] == (0.0, 0.0, 0.0)
    assert flags[1] == (1.0, 0.0, 1.0)   # x = 1.2 > 1: terminated, not truncated
    assert float(s.obs[0]) < 1.0          # auto-reset happened after the termination
    # Termination on the time-limit step counts as termination only.
    env2 = AutoResetWrapper(EpisodeWrapper(_Terminating(), episode_length=2))
    s = env2.step(env2.step(env2.reset(jax.random.PRNGKey(0)), jnp.array([0.6])), jnp.array([0.6]))
    assert (float(s.info["terminated"]), float(s.info["truncated"])) == (1.0, 0.0)


def test_default_budgets_are_reachable_by_every_built_in_explorer():
    from metapg_jax import strategy
    from metapg_jax.config import make_config, validate

    for name, spec in envs.TASKS.items():
        budget = envs.default_budget(name)
        assert budget % spec.eval_every == 0
        assert budget >= 0.99 * spec.paper_budget
        for method in strategy.explorers():  # each evaluates at the task's interval: the same sample counts
            # (--method=own samples a stochastic student's policy: SAC's)
            student = "sac" if method == "own" else "ddpg"
            cfg = validate(make_config(name, method, physics="mujoco" if envs.has_mujoco(name) else "mjx",
                                       student=student))
            assert cfg.run.total_steps == budget and cfg.run.eval_every == spec.eval_every, (name, method)
