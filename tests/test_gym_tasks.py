"""Any gymnasium MuJoCo task on MuJoCo's C engine: ``gym:<Id>`` (envs/gym_generic.py).

The reference is gymnasium's own env (``gymnasium.make(id).unwrapped``, MuJoCo's C engine in float64), as in
tests/test_physics.py for the built-in tasks: from the same reset (gymnasium's ``reset(seed=s)`` with the seed
our reset draws) and the same controls, observations, rewards, reward components, terminated/truncated and
the integration state equal gymnasium's bit for bit (host, float64) and as float32 casts (the compiled
program, across its auto-resets).
"""

from __future__ import annotations

import dataclasses
import json
import os

import jax
import mujoco
import numpy as np
import pytest

import envs
from envs.gym_generic import GymnasiumCEnv
from envs.gym_names import make_gymnasium_env, parse_name
from envs.mujoco_c import STATE_SPEC

# Two envs per batch: full-range random actions (Walker2d falls within the episode) and actions scaled by 0.1.
SCALES = (1.0, 0.1)
STEPS = 200


def _gym_state(data) -> np.ndarray:
    state = np.empty(mujoco.mj_stateSize(data.model, STATE_SPEC))
    mujoco.mj_getState(data.model, data, state, STATE_SPEC)
    return state


def _actions(nu, steps, seed=0):
    rng = np.random.default_rng(seed)
    a = rng.uniform(-1, 1, (steps, len(SCALES), nu)) * np.array(SCALES)[None, :, None]
    return a.astype(np.float32)


@pytest.fixture(scope="module", params=["Walker2d-v5", "Ant-v5"])
def task(request):
    name = f"gym:{request.param}"
    return name, envs.make_raw(name, physics="mujoco")


def test_host_steps_equal_gymnasium_bit_for_bit(task):
    """gymnasium's reset(seed) and 200 steps (on past a termination, as gymnasium's unwrapped env steps): obs,
    reward, terminated, every scalar info entry and the integration state equal gymnasium's at every step.
    (Ant's reward reads the torso's xpos *before* the step, as the previous step left it: the replay row.)"""
    name, env = task
    host = env.host
    gyms = [make_gymnasium_env(name) for _ in SCALES]
    seeds = np.array([11, 2**64 - 5], dtype=object)
    rows, obs = host.reset(seeds)
    for i, g in enumerate(gyms):
        g_obs, _ = g.reset(seed=int(seeds[i]))
        np.testing.assert_array_equal(obs[i], g_obs)
        np.testing.assert_array_equal(host.integration_state(rows)[i], _gym_state(g.data))
    actions = _actions(host.nu, STEPS)
    terminated_any = False
    for t in range(STEPS):
        r = host.step(rows, actions[t])
        states = host.integration_state(r["rows"])
        for i, g in enumerate(gyms):
            g_obs, g_rew, g_term, g_trunc, g_info = g.step(r["ctrl"][i])
            where = f"{name} env {i} step {t}"
            np.testing.assert_array_equal(r["next_obs"][i], g_obs, err_msg=where)
            assert r["reward"][i] == g_rew, where
            assert bool(r["terminated"][i]) == g_term and not g_trunc, where
            for k in host.metric_keys:
                assert r["metrics"][k][i] == g_info[k], f"{where}: {k}"
            np.testing.assert_array_equal(states[i], _gym_state(g.data), err_msg=where)
            terminated_any |= g_term
        rows = r["rows"]
    assert terminated_any, f"{name}: the random actions should end an episode"
    assert {"reward_forward", "reward_ctrl", "reward_survive"} <= set(host.metric_keys)


def test_the_compiled_program_gives_gymnasiums_episodes_across_auto_resets(task):
    """envs.make(gym:..., physics='mujoco') in jit + vmap + scan with a 60-step time limit: every step's float32
    obs, reward and flags are gymnasium's numbers cast, through terminations, truncations and the auto-resets
    between them, each of which is gymnasium's reset(seed) with the seed drawn from the wrapper's key."""
    name, _ = task
    length, steps = 60, 150
    wrapped = envs.make(name, physics="mujoco", episode_length=length)
    raw = wrapped.unwrapped
    keys = jax.random.split(jax.random.PRNGKey(3), len(SCALES))
    actions = _actions(raw.action_size, steps, seed=1)

    @jax.jit
    def run(keys, actions):
        s = jax.vmap(wrapped.reset)(keys)

        def body(s, a):
            reset_key = s.info["reset_key"]
            s = jax.vmap(wrapped.step)(s, a)
            return s, (s.info["next_obs"], s.reward, s.info["terminated"], s.info["truncated"], s.obs, reset_key)

        return s.obs, jax.lax.scan(body, s, actions)[1]

    obs0, (next_obs, reward, term, trunc, obs, reset_keys) = jax.tree.map(np.asarray, run(keys, actions))
    ctrl = raw.host.scale_action(np.clip(actions, -1, 1))
    ends = 0
    for i in range(len(SCALES)):
        g = make_gymnasium_env(name)
        # AutoResetWrapper.reset: the first episode from split(key)[1]; each auto-reset from split(reset_key)[1].
        g_obs, _ = g.reset(seed=raw.reset_seed(jax.random.split(keys[i])[1]))
        np.testing.assert_array_equal(obs0[i], g_obs.astype(np.float32))
        t_episode = 0
        for t in range(steps):
            g_obs, g_rew, g_term, _, _ = g.step(ctrl[t, i])
            t_episode += 1
            g_trunc = t_episode == length and not g_term
            where = f"{name} env {i} step {t}"
            np.testing.assert_array_equal(next_obs[t, i], g_obs.astype(np.float32), err_msg=where)
            assert reward[t, i] == np.float32(g_rew), where
            assert (term[t, i], trunc[t, i]) == (float(g_term), float(g_trunc)), where
            if g_term or g_trunc:
                ends += 1
                g_obs, _ = g.reset(seed=raw.reset_seed(jax.random.split(reset_keys[t, i])[1]))
                t_episode = 0
            np.testing.assert_array_equal(obs[t, i], g_obs.astype(np.float32), err_msg=where)
    assert ends >= 2 * len(SCALES)


def test_threads_step_gymnasiums_envs_to_the_numbers_of_one_thread(monkeypatch):
    """The host on 1 and 3 threads (three gymnasium instances, each stepping a slice of the batch) from the same
    rows, actions and reset seeds (Walker2d, 5 envs, 80 steps through terminations and forced resets): every
    output bit for bit the same; the integration state too. One thread unless asked (threads slow it down)."""
    from envs.gym_generic import GymnasiumHost
    from envs.host_call import THREADS_VARIABLE

    name, n = "gym:Walker2d-v5", 5
    monkeypatch.delenv(THREADS_VARIABLE, raising=False)
    assert GymnasiumHost(name).threads == 1
    monkeypatch.setenv(THREADS_VARIABLE, "2")
    assert GymnasiumHost(name).threads == 2
    one, three = GymnasiumHost(name, threads=1), GymnasiumHost(name, threads=3)
    seeds = np.array([3, 1, 4, 1, 5], dtype=object)
    (rows1, obs1), (rows3, obs3) = one.reset(seeds), three.reset(seeds)
    np.testing.assert_array_equal(rows1, rows3)
    np.testing.assert_array_equal(obs1, obs3)
    rng = np.random.default_rng(9)
    ended = 0
    for t in range(80):
        a = rng.uniform(-1, 1, (n, one.nu))
        reset_seeds = np.array([int(x) for x in rng.integers(0, 2**63, n)], dtype=object)
        force = rng.uniform(size=n) < 0.03
        r1, r3 = one.step(rows1, a, reset_seeds, force), three.step(rows3, a, reset_seeds, force)
        for k in ("rows", "obs", "next_obs", "reward", "terminated", "ctrl"):
            np.testing.assert_array_equal(r1[k], r3[k], err_msg=f"{k} at step {t}")
        for k in one.metric_keys:
            np.testing.assert_array_equal(r1["metrics"][k], r3["metrics"][k], err_msg=f"{k} at step {t}")
        ended += int((r1["terminated"] | force).sum())
        rows1, rows3 = r1["rows"], r3["rows"]
    np.testing.assert_array_equal(one.integration_state(rows1), three.integration_state(rows3))
    assert ended > 0 and len(three._replayers) == 3


@pytest.mark.parametrize("gym_id", ["Swimmer-v5", "Humanoid-v5"])
def test_other_tasks_have_gymnasiums_sizes_and_step_finitely(gym_id):
    name = f"gym:{gym_id}"
    g = make_gymnasium_env(name)
    env = envs.make(name, physics="auto")
    assert type(env.unwrapped) is GymnasiumCEnv
    assert env.observation_size == g.observation_space.shape[0]
    assert env.action_size == g.action_space.shape[0]
    assert envs.get_spec(name).episode_length == 1000
    step = jax.jit(jax.vmap(env.step))
    s = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 2))
    for a in _actions(env.action_size, 5, seed=2):
        s = step(s, a)
        assert np.isfinite(np.asarray(s.obs)).all() and np.isfinite(np.asarray(s.reward)).all()
    assert s.obs.shape == (2, g.observation_space.shape[0])


def test_the_env_state_carried_through_the_host_continues_bit_for_bit():
    """What a checkpoint does to the env state (device_get, then device_put on resume): the continuation
    equals the uninterrupted run, leaf for leaf."""
    env = envs.make("gym:Ant-v5", physics="mujoco", episode_length=30)
    actions = _actions(env.action_size, 40, seed=3)
    run = jax.jit(lambda s, a: jax.lax.scan(lambda s, a: (jax.vmap(env.step)(s, a), None), s, a)[0])
    s0 = jax.vmap(env.reset)(jax.random.split(jax.random.PRNGKey(5), len(SCALES)))
    whole = run(run(s0, actions[:20]), actions[20:])
    stored = jax.device_get(run(s0, actions[:20]))
    resumed = run(jax.device_put(stored), actions[20:])
    for a, b in zip(jax.tree.leaves(whole), jax.tree.leaves(resumed)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


@pytest.mark.slow
def test_a_gym_task_trains_from_the_command_line_and_resumes_bit_for_bit(tmp_path):
    """experiments.run --env=gym:Walker2d-v5(...) (the C engine by default): a tiny TD3 run, extended by --resume
    from its checkpoint, equals the run started with the longer budget. config.json keeps the task's name
    (keyword arguments included) for --resume; the default folder name has no colon."""
    from experiments import run
    from tests.helpers import assert_same_run, tiny_argv

    name = "gym:Walker2d-v5(ctrl_cost_weight=0.01)"
    argv = [*tiny_argv("ddpg", env=name), "--noise=normal", "--student=td3",
            "--set", "run.buffer_size=600"]
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        assert run.main(argv + ["--steps=300"]) == 0
    finally:
        os.chdir(cwd)
    (out,) = (tmp_path / "runs").iterdir()
    assert out.name == "gym-Walker2d-v5-ctrl_cost_weight=0.01-ddpg-td3-paper-mujoco-s0"
    stored = json.load(open(out / "config.json"))
    assert stored["config"]["env"]["name"] == name and stored["config"]["env"]["physics"] == "mujoco"
    summary = json.load(open(out / "summary.json"))
    assert summary["env"] == name and np.isfinite(summary["final_return_per_seed"]).all()
    assert run.main(["--resume", str(out), "--steps=600", "--quiet", "--no-plot"]) == 0
    assert run.main(argv + ["--steps=600", "--out", str(tmp_path / "full")]) == 0
    assert_same_run(str(tmp_path / "full"), str(out))
    # experiments.export --replay: gymnasium's env with the task's keyword arguments (the control cost is 10x
    # gymnasium's default here, so a replay without them would give other returns)
    from experiments import export

    report, policy = tmp_path / "replay.json", str(tmp_path / "p.npz")
    assert export.main([str(out), "--out", policy, "--replay", "1", "--report", str(report)]) == 0
    got = json.load(open(report))
    assert (got["reference"], got["gym_id"], got["gym_kwargs"]) == ("gymnasium", "Walker2d-v5", {"ctrl_cost_weight": 0.01})
    returns = got["seeds"][0]["replay_returns"]
    assert returns == export.replay_in_gymnasium(policy, "Walker2d-v5", 0, 1, ctrl_cost_weight=0.01)
    assert returns != export.replay_in_gymnasium(policy, "Walker2d-v5", 0, 1)


def test_names_with_keyword_arguments():
    assert parse_name("gym:Walker2d-v5") == ("Walker2d-v5", ())
    assert parse_name("gym:Ant-v5(ctrl_cost_weight=0.1, healthy_z_range=(0.3, inf), xml_file='ant.xml')") == (
        "Ant-v5", (("ctrl_cost_weight", 0.1), ("healthy_z_range", (0.3, float("inf"))), ("xml_file", "ant.xml")))
    env = envs.make_raw("gym:Ant-v5(include_cfrc_ext_in_observation=False)", physics="mujoco")
    assert env.observation_size == 27  # 105 with the contact forces
    spec = envs.get_spec("gym:Reacher-v5")
    assert (spec.gym_id, spec.episode_length, spec.paper_budget) == ("Reacher-v5", 50, 1_000_000)
    assert envs.default_budget("gym:Walker2d-v5") == 990_000


@pytest.mark.parametrize("name, message", [
    ("gym:CartPole-v1", "gym:CartPole-v1: CartPole-v1 is not a MuJoCo env"),
    ("gym:Nope-v5", "unknown task 'gym:Nope-v5': gymnasium has no env 'Nope-v5'"),
    ("gym:Hopper-v3", "gym:Hopper-v3: Hopper-v3 is not a MuJoCo env"),  # mujoco_py
    ("gym:Ant-v5(nope=1)", "gym:Ant-v5(nope=1): Ant-v5 takes no keyword argument 'nope'"),
    ("gym:Ant-v5(x=y)", "gym:Ant-v5(x=y): x=y is not a literal"),
    ("walker2d", "unknown task 'walker2d'; valid tasks: pendulum"),
])
def test_unknown_and_non_mujoco_ids_are_refused_in_one_line(name, message):
    with pytest.raises(ValueError) as err:
        envs.get_spec(name)
    assert str(err.value).startswith(message) and "\n" not in str(err.value), str(err.value)


def test_mjx_and_brax_are_refused_for_a_gym_task():
    with pytest.raises(ValueError, match=r"gym:Walker2d-v5 runs on MuJoCo's C engine only \(--physics=mujoco\): "
                                         r"its observation, reward and termination are gymnasium's own Python code"):
        envs.make("gym:Walker2d-v5", physics="mjx")
    with pytest.raises(ValueError, match="gymnasium's own env: --source=brax does not apply"):
        envs.make("gym:Walker2d-v5", source="brax", physics="mujoco")
    assert envs.resolve_physics("gym:Walker2d-v5", "gymnasium", "auto", backend="gpu") == "mujoco"
    from metapg_jax.config import make_config, validate

    cfg = make_config("gym:Walker2d-v5", "ddpg", physics="auto")
    assert cfg.env.physics == "mujoco" and cfg.episode_length == 1000
    with pytest.raises(ValueError, match="runs on MuJoCo's C engine only"):
        validate(dataclasses.replace(cfg, env=dataclasses.replace(cfg.env, physics="mjx")))


@pytest.mark.parametrize("argv, message", [
    (["--env=gym:CartPole-v1"], "error: gym:CartPole-v1: CartPole-v1 is not a MuJoCo env"),
    (["--env=gym:Nope-v5"], "error: unknown task 'gym:Nope-v5'"),
    (["--env=gym:Walker2d-v5", "--physics=mjx"], "error: gym:Walker2d-v5 runs on MuJoCo's C engine only"),
    (["--env=gym:Walker2d-v5(ctrl_cost_weight='a')"], "error: gym:Walker2d-v5(ctrl_cost_weight='a'): "
                                                      "gymnasium's env failed on a probe step: TypeError"),
])
def test_cli_refuses_them_before_compiling(argv, message, tmp_path, capsys):
    from tests.helpers import assert_run_refuses

    assert_run_refuses(argv + ["--method=ddpg"], message, tmp_path, capsys)
