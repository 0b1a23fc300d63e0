"""DeepMind Control suite tasks, ``dmc:<domain>-<task>`` (envs/dmc.py, envs/dmc_names.py).

The reference is dm_control's own suite (``suite.load(domain, task)``, MuJoCo's C engine in float64): from the
same initial state (qpos, qvel and, for Reacher and finger-turn, the target's position; for cheetah the draw that
its reset settles) and the same actions, the compiled program on the C engine gives dm_control's observations and
rewards cast to float32, bit for bit, for a whole episode, and ends it where dm_control does (the 1,000-step time
limit). MJX agrees within float32 round-off (tests/test_dmc_locomotion.py: the contact-rich domains).
"""

from __future__ import annotations

import json
import os

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

import envs
from envs import dmc_names

os.environ.setdefault("MUJOCO_GL", "disable")  # dm_control's suite needs no renderer here
suite = pytest.importorskip("dm_control.suite")


def _flat(observation) -> np.ndarray:
    """dm_control's OrderedDict observation as one vector, in its key order."""
    return np.concatenate([np.asarray(v, np.float64).ravel() for v in observation.values()])


def _dm_start(name, seed):
    """dm_control's env of ``name`` after its reset, and the state to start ours from: qpos, qvel, model params.
    For a task that settles its reset (cheetah) that is the draw, which our reset settles: dm_control's reset
    draws it first from ``RandomState(seed)``."""
    domain, task = dmc_names.parse_name(f"dmc:{name}")
    env = suite.load(domain, task, task_kwargs={"random": seed})
    ts = env.reset()
    raw = envs.make_raw(f"dmc:{name}", physics="mujoco")
    model = env.physics.model
    params = [np.asarray(getattr(model, field)).reshape(-1)[index] for field, index in raw.task.model_params]
    qpos, qvel = env.physics.data.qpos.copy(), env.physics.data.qvel.copy()
    if raw.task.settle_steps:
        limited = model.jnt_limited == 1
        qpos, qvel = model.qpos0.copy(), np.zeros_like(qvel)
        qpos[limited] = np.random.RandomState(seed).uniform(*model.jnt_range[limited].T)
    return env, ts, (qpos, qvel, np.array(params))


# Every task (each costs a C-engine compile and 1,000 dm_control steps: 1-3 s); four of them in the fast tier: one
# per kind of reset (plain, rejection, a model parameter) and finger-turn_hard (sensors, touch, both rejection and
# a model parameter).
FAST = ("cartpole-swingup_sparse", "ball_in_cup-catch", "reacher-hard", "finger-turn_hard")


@pytest.mark.parametrize("name", [n if n in FAST else pytest.param(n, marks=pytest.mark.slow)
                                  for n in dmc_names.TASKS])
def test_the_compiled_c_engine_gives_dm_controls_episode(name):
    """A whole episode (1,000 steps) of uniform random actions through envs.make's wrappers in jit: observations
    and rewards are dm_control's float64 numbers cast to float32, and the episode ends at dm_control's last
    step, truncated (discount 1), never terminated."""
    steps = dmc_names.EPISODE_LENGTH
    dm, ts, (qpos, qvel, params) = _dm_start(name, seed=7)
    wrapped = envs.make(f"dmc:{name}", physics="mujoco")
    raw = wrapped.unwrapped
    start = raw.state_from_gymnasium(qpos, qvel, params)
    np.testing.assert_array_equal(np.asarray(start.obs), _flat(ts.observation).astype(np.float32))
    s = wrapped.reset(jax.random.PRNGKey(0))
    s = s.replace(pipeline_state=start.pipeline_state, obs=start.obs, info={**s.info, "next_obs": start.obs})
    actions = np.random.default_rng(1).uniform(-1, 1, (steps, raw.action_size)).astype(np.float32)

    @jax.jit
    def run(s, actions):
        def body(s, a):
            s = wrapped.step(s, a)
            return s, (s.info["next_obs"], s.reward, s.info["terminated"], s.info["truncated"])
        return jax.lax.scan(body, s, actions)[1]

    next_obs, reward, term, trunc = jax.tree.map(np.asarray, run(s, actions))
    for t in range(steps):
        ts = dm.step(actions[t].astype(np.float64))
        np.testing.assert_array_equal(next_obs[t], _flat(ts.observation).astype(np.float32), err_msg=f"step {t}")
        assert reward[t] == np.float32(ts.reward), f"step {t}"
        assert term[t] == 0.0 and trunc[t] == float(ts.last()), f"step {t}"
    assert ts.last() and ts.discount == 1.0 and trunc[-1] == 1.0
    assert np.ptp(next_obs[:, 0]) > 0.01  # the physics moved


@pytest.mark.parametrize("name", FAST)
def test_the_host_gives_dm_controls_float64_numbers(name):
    """On the host (no program, float64), 300 steps: observations and rewards are dm_control's to the bit."""
    dm, ts, (qpos, qvel, params) = _dm_start(name, seed=3)
    host = envs.make_raw(f"dmc:{name}", physics="mujoco").host
    rows, obs = host.reset(qpos[None], qvel[None], params[None])
    np.testing.assert_array_equal(obs[0], _flat(ts.observation))
    actions = np.random.default_rng(2).uniform(-1, 1, (300, 1, host.nu)).astype(np.float32)
    for t in range(len(actions)):
        r = host.step(rows, actions[t])
        ts = dm.step(actions[t, 0].astype(np.float64))
        np.testing.assert_array_equal(r["next_obs"][0], _flat(ts.observation), err_msg=f"step {t}")
        assert r["reward"][0] == ts.reward, f"step {t}"
        rows = r["rows"]


def test_the_c_engine_step_computes_the_new_states_frames():
    """dm_control's step ends with mj_step1, so the frames the observation reads are the new state's: on the
    host, our state rows rebuilt by mj_forward give the same observation as the step returned."""
    raw = envs.make_raw("dmc:cartpole-swingup", physics="mujoco")
    host = raw.host
    rows, _ = host.reset(np.array([[0.1, 3.0]]), np.array([[0.5, -2.0]]))
    for _ in range(3):
        r = host.step(rows, np.array([[0.7]], np.float32))
        rows = r["rows"]
        data = mujoco.MjData(raw.mj_model)
        mujoco.mj_setState(raw.mj_model, data, rows[0, :host.nstate], mujoco.mjtState.mjSTATE_INTEGRATION)
        mujoco.mj_forward(raw.mj_model, data)
        np.testing.assert_array_equal(r["next_obs"][0, 1:3], data.xmat[2, [8, 2]])


@pytest.mark.slow
def test_mjx_matches_the_c_engine_on_cartpole():
    """MJX (float32) against the C engine from the same reset, 100 steps of random actions: observations within
    5e-6 and rewards within 1e-6 (measured: 1e-6 and 5e-8)."""
    c = envs.make_raw("dmc:cartpole-swingup", physics="mujoco")
    m = envs.make_raw("dmc:cartpole-swingup", physics="mjx")
    keys = jax.random.split(jax.random.PRNGKey(3), 2)
    actions = jax.random.uniform(jax.random.PRNGKey(4), (100, 2, 1), minval=-1.0, maxval=1.0)

    def run(env):
        def body(s, a):
            s = jax.vmap(env.step)(s, a)
            return s, (s.obs, s.reward)
        return jax.jit(lambda k: jax.lax.scan(body, jax.vmap(env.reset)(k), actions)[1])(keys)

    (obs_m, rew_m), (obs_c, rew_c) = run(m), run(c)
    np.testing.assert_allclose(np.asarray(obs_m), np.asarray(obs_c), rtol=0, atol=5e-6)
    np.testing.assert_allclose(np.asarray(rew_m), np.asarray(rew_c), rtol=0, atol=1e-6)


def test_sparse_rewards_are_reached():
    """The sparse rewards pay 1 where dm_control does: cartpole-balance_sparse from its resets with zero action
    (the pole starts within 0.034 rad of upright, the cart within 0.1), ball_in_cup with the ball placed in the
    cup, reacher with the target under the finger."""
    bal = envs.make("dmc:cartpole-balance_sparse", physics="mujoco")
    s = jax.jit(jax.vmap(bal.reset))(jax.random.split(jax.random.PRNGKey(0), 8))
    s = jax.jit(jax.vmap(bal.step))(s, jnp.zeros((8, 1)))
    np.testing.assert_array_equal(np.asarray(s.reward), np.ones(8, np.float32))
    cup = envs.make_raw("dmc:ball_in_cup-catch", physics="mujoco")
    # The cup at its origin (z 0.6): its target box is centred at z 0.55; the ball (whose slide starts at z 0.2)
    # there, at rest.
    start = cup.state_from_gymnasium(np.array([0.0, 0.0, 0.0, 0.35]), np.zeros(4))
    assert float(jax.jit(cup.step)(start, jnp.zeros(2)).reward) == 1.0
    reacher = envs.make_raw("dmc:reacher-hard", physics="mujoco")
    # Both joints at 0: the finger is at x = 0.12 + 0.12 (the hand and finger bodies' offsets), y = 0.
    start = reacher.state_from_gymnasium(np.zeros(2), np.zeros(2), np.array([0.24, 0.0]))
    assert float(jax.jit(reacher.step)(start, jnp.zeros(2)).reward) == 1.0


@pytest.mark.parametrize("name", ["ball_in_cup-catch", "finger-turn_hard"])
def test_rejecting_resets_keep_the_first_draw_without_contacts(name):
    """dm_control redraws ball_in_cup's ball while it touches the cup, and finger's joints while any geoms touch;
    we draw 16 candidates and keep the first without contacts. Over 64 resets some first draws touch (~18% and
    ~9% do), and every reset is the first free candidate."""
    raw = envs.make_raw(f"dmc:{name}", physics="mujoco")
    keys = jax.random.split(jax.random.PRNGKey(0), 64)
    tries = np.asarray(jax.vmap(raw.task.sample_reset)(keys), np.float64)
    rows = np.asarray(jax.jit(jax.vmap(raw.reset))(keys).pipeline_state).view(np.float64)
    model, data = raw.mj_model, mujoco.MjData(raw.mj_model)
    nq = model.nq

    def touches(qpos):
        mujoco.mj_resetData(model, data)
        data.qpos[:] = qpos
        mujoco.mj_forward(model, data)
        return data.ncon > 0

    first_touch = 0
    for i in range(len(keys)):
        touch = [touches(q) for q in tries[i, :, :nq]]
        first_touch += touch[0]
        np.testing.assert_array_equal(rows[i, 1:1 + nq], tries[i, touch.index(False), :nq])
    assert first_touch > 0


@pytest.mark.slow
def test_a_dmc_task_trains_from_the_command_line_and_resumes_bit_for_bit(tmp_path):
    """experiments.run --env=dmc:cartpole-swingup_sparse (the C engine by default on a CPU): a tiny DDPG run,
    extended by --resume from its checkpoint, equals the run started with the longer budget."""
    from experiments import run
    from tests.helpers import assert_same_run, tiny_argv

    argv = [*tiny_argv("ddpg", env="dmc:cartpole-swingup_sparse"), "--noise=normal",
            "--set", "run.buffer_size=600"]
    out, full = tmp_path / "run", tmp_path / "full"
    assert run.main(argv + ["--steps=300", "--out", str(out)]) == 0
    stored = json.load(open(out / "config.json"))
    assert stored["config"]["env"]["name"] == "dmc:cartpole-swingup_sparse"
    assert stored["config"]["env"]["physics"] == "mujoco"
    assert run.main(["--resume", str(out), "--steps=600", "--quiet", "--no-plot"]) == 0
    assert run.main(argv + ["--steps=600", "--out", str(full)]) == 0
    assert_same_run(str(full), str(out))
    # The exported policies replayed in dm_control's own suite (experiments.export --replay).
    from experiments import export

    report = tmp_path / "replay.json"
    assert export.main([str(out), "--out", str(tmp_path / "p.npz"), "--replay", "2", "--report", str(report)]) == 0
    got = json.load(open(report))
    assert got["reference"] == "dm_control" and got["dm_control"] == "dmc:cartpole-swingup_sparse"
    for seed in got["seeds"]:
        assert len(seed["replay_returns"]) == 2 and all(0.0 <= r <= 1000.0 for r in seed["replay_returns"])
        assert seed["replay_returns"] == export.replay_in_dm_control(str(tmp_path / "p.npz"),
                                                                     "dmc:cartpole-swingup_sparse", seed["seed"], 2)


def test_spec_and_engines():
    spec = envs.get_spec("dmc:reacher-hard")
    assert (spec.episode_length, spec.paper_budget, spec.eval_every) == (1000, 500_000, 9_000)
    assert envs.default_budget("dmc:reacher-hard") == 495_000
    assert envs.display_name("dmc:ball_in_cup-catch") == "ball_in_cup-catch"
    assert envs.has_mujoco("dmc:cartpole-swingup")
    assert envs.resolve_physics("dmc:cartpole-swingup", "gymnasium", "auto") == "mujoco"
    assert envs.resolve_physics("dmc:cartpole-swingup", "gymnasium", "auto", backend="gpu") == "mjx"
    sizes = {"cartpole-swingup": (5, 1), "pendulum-swingup": (3, 1), "ball_in_cup-catch": (8, 2),
             "reacher-easy": (6, 2), "point_mass-easy": (4, 2), "acrobot-swingup": (6, 1)}
    for name, (obs, act) in sizes.items():
        env = envs.make_raw(f"dmc:{name}", physics="mujoco")
        assert (env.observation_size, env.action_size) == (obs, act), name
    assert envs.make_raw("dmc:ball_in_cup-catch", physics="mujoco").frame_skip == 10


@pytest.mark.parametrize("name, message", [
    ("dmc:humanoid-run", "unknown task 'dmc:humanoid-run': no DeepMind Control domain 'humanoid' here; domains: "
                         "acrobot, ball_in_cup, cartpole, cheetah, finger, hopper"),
    ("dmc:cartpole-run", "unknown task 'dmc:cartpole-run': domain cartpole has the tasks balance, "
                         "balance_sparse, swingup, swingup_sparse"),
    ("dmc:cartpole", "bad task name 'dmc:cartpole': expected dmc:<domain>-<task>"),
    ("dmc:Cartpole-Swingup", "bad task name 'dmc:Cartpole-Swingup'"),
])
def test_bad_names_are_refused_in_one_line(name, message):
    with pytest.raises(ValueError) as err:
        envs.get_spec(name)
    assert str(err.value).startswith(message) and "\n" not in str(err.value), str(err.value)


def test_without_dm_control_the_install_command_is_named(monkeypatch):
    import importlib.util

    find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda n, *a: None if n == "dm_control" else find_spec(n, *a))
    with pytest.raises(ValueError, match=r'dmc:cartpole-swingup needs the dm_control package .*: '
                                         r'pip install -e "\.\[dmc\]"$'):
        envs.get_spec("dmc:cartpole-swingup")


@pytest.mark.parametrize("argv, message", [
    (["--env=dmc:humanoid-run"], "error: unknown task 'dmc:humanoid-run'"),
    (["--env=dmc:cartpole-run"], "error: unknown task 'dmc:cartpole-run'"),
    (["--env=dmc:cartpole"], "error: bad task name 'dmc:cartpole'"),
    (["--env=dmc:cartpole-swingup", "--source=brax"], "error: dmc:cartpole-swingup is a DeepMind Control task"),
])
def test_cli_refuses_them_before_compiling(argv, message, tmp_path, capsys):
    from tests.helpers import assert_run_refuses

    assert_run_refuses(argv + ["--method=ddpg"], message, tmp_path, capsys)
