"""MountainCarContinuous (envs/mountain_car.py) against gymnasium's MountainCarContinuous-v0: one step from
gymnasium's states through every branch of its step, whole episodes from its own resets (a random policy, one that
reaches the goal, out-of-range actions, a constant force against the goal), its reset distribution; a scripted
policy gets the goal's +100 in JAX; the task trains from the command line and is refused where it does not apply.

The standard: our float32 numbers against gymnasium's cast to float32. gymnasium keeps its state in float32 but
computes 0.0025 cos(3 x) in float64, which we compute in float32, so one step agrees to the last bit of the
velocity (``STEP_ATOL``); a velocity one bit off moves every later position, so over a whole episode positions
drift apart by up to ``EPISODE_ATOL`` (a few hundred float32 ulps of the position), while terminations, the step
of the +100 and the truncation at 999 steps are the same step for step, and rewards agree to one float32 ulp.
"""

import json
import os
import subprocess
import sys

import gymnasium
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

import envs
from envs.mountain_car import MountainCarContinuous

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TASK, GYM_ID, LENGTH = "mountain_car_continuous", "MountainCarContinuous-v0", 999
F32 = np.float32
# One step: (position, velocity) within a float32 ulp of a position in [1, 2) and of a velocity near the speed
# limit 0.07 (ulps 1.19e-7 and 7.45e-9).
STEP_ATOL = (1.2e-7, 7.5e-9)
# Whole episodes (999 steps): (position, velocity), about 3x the largest deviations of this module's comparison run
# with EPISODES = 100 (6.7e-5 and 2.9e-6, with out-of-range actions).
EPISODE_ATOL = (2e-4, 1e-5)
EPISODES = 6  # per policy


def _random(obs, rng):
    return rng.uniform(-1.0, 1.0, (1,)).astype(F32)


def _with_velocity(obs, rng):
    """Full force in the direction of motion (right from rest): reaches the goal in about 110 steps, after one
    swing to the left wall."""
    return np.array([1.0 if obs[1] >= 0 else -1.0], F32)


def _out_of_range(obs, rng):
    return rng.uniform(-3.0, 3.0, (1,)).astype(F32)


def _full_left(obs, rng):
    """A constant force, against the goal: the car swings on the left slope until the time limit."""
    return np.array([-1.0], F32)


POLICIES = {"random": _random, "with_velocity": _with_velocity, "out_of_range": _out_of_range, "full_left": _full_left}


def _gym_episode(seed, policy):
    """gymnasium's episode from ``reset(seed=seed)`` (its TimeLimit of 999 steps included): the reset observation
    and, per step, the action and gymnasium's observation, reward, terminated and truncated."""
    env = gymnasium.make(GYM_ID)
    assert env.spec.max_episode_steps == LENGTH
    obs0, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    obs, rows = obs0, []
    while not rows or not (rows[-1][3] or rows[-1][4]):
        action = policy(obs, rng)
        obs, reward, terminated, truncated, _ = env.step(action)
        rows.append((action, obs, reward, terminated, truncated))
    actions, observations, rewards, terminated, truncated = (np.array(c) for c in zip(*rows))
    return obs0, actions, observations, rewards, terminated, truncated


def _rollout(env):
    """jit(vmap) of: from (position, velocity) at reset, ``LENGTH`` steps of the wrapped env with the given actions;
    per step the observation the step produced (before any auto-reset), reward, terminated, truncated and the
    episode's return so far."""
    def one(q0, actions):
        state = env.reset(jax.random.PRNGKey(0))
        state = state.replace(pipeline_state=q0, obs=q0)

        def step(state, action):
            state = env.step(state, action)
            i = state.info
            return state, (i["next_obs"], state.reward, i["terminated"], i["truncated"], i["episode_return"])

        return jax.lax.scan(step, state, actions)[1]

    return jax.jit(jax.vmap(one))


def test_the_spec_is_gymnasiums_task():
    """The registry's entry: gymnasium's id, time limit, spaces (its action box is our [-1, 1], so actions are not
    scaled); a JAX task outside the paper's grid, with a default budget of whole evaluation intervals."""
    spec, genv = envs.get_spec(TASK), gymnasium.make(GYM_ID)
    assert spec.gym_id == MountainCarContinuous.gym_id == GYM_ID and spec.episode_length == genv.spec.max_episode_steps
    env = envs.make(TASK)
    assert (env.observation_size, env.action_size) == (genv.observation_space.shape[0], genv.action_space.shape[0])
    assert (genv.action_space.low, genv.action_space.high) == (-1, 1)
    assert not envs.has_mujoco(TASK) and TASK not in envs.paper_tasks()
    assert envs.display_name(TASK) == "MountainCarContinuous"
    assert envs.default_budget(TASK) == spec.paper_budget == 60_000 and spec.eval_every % 3000 == 0


def test_one_step_from_gymnasiums_states_through_every_branch():
    """From 4,096 float32 states spread over the observation box (gymnasium's state after any step is float32),
    actions in [-2, 2]: the left wall, the speed limit, the right edge, the goal, with and without a goal velocity
    (gymnasium's one argument)."""
    rng = np.random.default_rng(0)
    n = 4096
    q = np.stack([rng.uniform(-1.2, 0.6, n), rng.uniform(-0.07, 0.07, n)], axis=1).astype(F32)
    q[:8] = [[-1.2, 0.0], [-1.2, -0.07], [-1.19, -0.05], [0.59, 0.069], [0.44, 0.02], [-0.52, 0.0699],
             [-0.52, -0.0699], [0.45, 0.0]]
    actions = rng.uniform(-2.0, 2.0, (n, 1)).astype(F32)
    actions[:8] = [[0.0], [-1.0], [-1.0], [1.0], [1.0], [1.0], [-1.0], [0.0]]
    for goal_velocity in (0.0, 0.02):
        genv = gymnasium.make(GYM_ID, goal_velocity=goal_velocity).unwrapped
        genv.reset(seed=0)
        expected = []
        for state, action in zip(q, actions):
            genv.state = state.copy()
            obs, reward, terminated, _, _ = genv.step(action)
            expected.append((obs, reward, terminated))
        g_obs, g_reward, g_terminated = (np.array(c) for c in zip(*expected))
        env = envs.make_raw(TASK, goal_velocity=goal_velocity)
        states = jax.vmap(env.state_from_q)(q[:, 0], q[:, 1])
        out = jax.jit(jax.vmap(env.step))(states, jnp.asarray(actions))
        np.testing.assert_allclose(out.obs[:, 0], g_obs[:, 0], rtol=0, atol=STEP_ATOL[0])
        np.testing.assert_allclose(out.obs[:, 1], g_obs[:, 1], rtol=0, atol=STEP_ATOL[1])
        np.testing.assert_array_max_ulp(np.asarray(out.reward), g_reward.astype(F32), maxulp=1)
        np.testing.assert_array_equal(np.asarray(out.done).astype(bool), g_terminated)
        # Every branch of gymnasium's step happened (each count out of 4,096).
        at_wall = (g_obs[:, 0] == F32(-1.2)) & (q[:, 1] < 0)
        assert at_wall.sum() > 20 and (g_obs[at_wall, 1] == 0).all()
        assert (np.abs(g_obs[:, 1]) == F32(0.07)).sum() > 20
        assert (g_obs[:, 0] == F32(0.6)).sum() > 20
        assert (np.abs(actions[:, 0]) > 1).sum() > 1000 and g_terminated.sum() > 100
        assert (g_reward[g_terminated] > 90).all() and (g_reward[~g_terminated] <= 0).all()
        at_goal = g_obs[:, 0] >= F32(0.45)
        leaving, slow = at_goal & (g_obs[:, 1] < 0), at_goal & (g_obs[:, 1] >= 0) & (g_obs[:, 1] < goal_velocity)
        assert leaving.any() and not g_terminated[leaving | slow].any() and slow.any() == (goal_velocity > 0)


def test_whole_episodes_from_gymnasiums_resets_equal_gymnasiums():
    """``envs.make`` (the time limit and auto-reset included) replays gymnasium's actions from gymnasium's reset
    states: every step's observation, reward, terminated and truncated, to the end of each episode."""
    episodes = [(name, seed, *_gym_episode(seed, policy))
                for name, policy in POLICIES.items() for seed in range(EPISODES)]
    q0 = jnp.asarray(np.stack([e[2] for e in episodes]))
    padded = np.zeros((len(episodes), LENGTH, 1), F32)
    for i, e in enumerate(episodes):
        padded[i, :len(e[3])] = e[3]
    obs, reward, terminated, truncated, ret = map(np.asarray, _rollout(envs.make(TASK))(q0, jnp.asarray(padded)))
    ends = {}
    for i, (name, seed, _, actions, g_obs, g_reward, g_terminated, g_truncated) in enumerate(episodes):
        n, where = len(actions), f"{name}, seed {seed}"
        np.testing.assert_allclose(obs[i, :n, 0], g_obs[:, 0], rtol=0, atol=EPISODE_ATOL[0], err_msg=where)
        np.testing.assert_allclose(obs[i, :n, 1], g_obs[:, 1], rtol=0, atol=EPISODE_ATOL[1], err_msg=where)
        np.testing.assert_array_max_ulp(reward[i, :n], g_reward.astype(F32), maxulp=1)
        np.testing.assert_array_equal(terminated[i, :n].astype(bool), g_terminated, err_msg=where)
        np.testing.assert_array_equal(truncated[i, :n].astype(bool), g_truncated, err_msg=where)
        assert ret[i, n - 1] == pytest.approx(g_reward.sum(), rel=1e-5, abs=1e-3), where
        at_wall = ((g_obs[:, 0] == F32(-1.2)) & (g_obs[:, 1] == 0)).sum()
        ends.setdefault(name, []).append(("goal" if g_terminated[-1] else "time limit", n, g_reward[-1], at_wall))
    # The goal's +100 and its termination, after a stop at the left wall; the time limit at 999 steps; the actions
    # out of the box cost more.
    assert all(end == "goal" and n < 200 and reward > 99 and wall for end, n, reward, wall in ends["with_velocity"])
    assert all(end == "time limit" and n == LENGTH for end, n, _, _ in ends["random"] + ends["full_left"])
    assert max(abs(a) for e in episodes if e[0] == "out_of_range" for a in e[3].ravel()) > 2.9


def test_the_reset_distribution_is_gymnasiums():
    """Position U[-0.6, -0.4], velocity 0: ours (JAX's PRNG) and gymnasium's own draws (from its seeds) both."""
    env = envs.make_raw(TASK)
    ours = np.asarray(jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(1), 4000)).obs)
    theirs = np.array([gymnasium.make(GYM_ID).reset(seed=s)[0] for s in range(1000)])
    for obs in (ours, theirs):
        assert obs.dtype == F32 and (obs[:, 1] == 0).all()
        assert obs[:, 0].min() >= F32(-0.6) and obs[:, 0].max() <= F32(-0.4)
        assert stats.kstest(obs[:, 0], "uniform", args=(-0.6, 0.2)).pvalue > 0.01
    assert stats.ks_2samp(ours[:, 0], theirs[:, 0]).pvalue > 0.01


def test_pushing_with_the_velocity_reaches_the_goal_and_standing_still_does_not():
    """In JAX, 64 resets: full force in the direction of motion ends every first episode at the goal, the last
    step worth 100 - 0.1 and the episode 100 - 0.1 per step; no force (the best return without the goal, 0) never
    gets there and is truncated at 999 steps."""
    env = envs.make(TASK)

    @jax.jit
    @jax.vmap
    def first_episode(key, push):
        def step(state, _):
            action = jnp.where(push, jnp.where(state.obs[1] >= 0, 1.0, -1.0), 0.0)[None]
            state = env.step(state, action)
            return state, (state.reward, state.info["terminated"], state.info["truncated"],
                           state.info["episode_return"], state.info["episode_length"])

        return jax.lax.scan(step, env.reset(key), None, length=LENGTH)[1]

    keys = jax.random.split(jax.random.PRNGKey(7), 64)
    for push in (True, False):
        reward, terminated, truncated, ret, length = map(np.asarray, first_episode(keys, jnp.full(64, push)))
        end = np.argmax((terminated + truncated) > 0, axis=1)
        rows = np.arange(64)
        if push:
            assert (terminated[rows, end] == 1).all() and (truncated[rows, end] == 0).all() and (end < 200).all()
            np.testing.assert_allclose(reward[rows, end], 100.0 - 0.1, rtol=1e-6)
            np.testing.assert_allclose(ret[rows, end], 100.0 - 0.1 * length[rows, end], rtol=1e-5)
            assert (length[rows, end] == end + 1).all()
        else:
            assert (terminated == 0).all() and (truncated[:, LENGTH - 1] == 1).all() and (end == LENGTH - 1).all()
            assert (ret[:, LENGTH - 1] == 0).all()


@pytest.mark.parametrize("argv, message", [
    (["--env=mountain_car"], "valid tasks: pendulum, inverted_pendulum, inverted_double_pendulum, hopper, "
                             "halfcheetah, reacher, mountain_car_continuous, gym:<Id>"),
    ([f"--env={TASK}", "--physics=mujoco"], f"{TASK} is a JAX task without MuJoCo physics"),
    ([f"--env={TASK}", "--source=brax"], f"{TASK} has only the gymnasium source"),
])
def test_the_command_line_refuses_what_does_not_apply(argv, message, capsys):
    from experiments import run

    assert run.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err


def test_the_benchmark_plans_the_task(tmp_path, capsys, monkeypatch):
    """``experiments.benchmark --tasks`` takes it: its cells run on JAX (no --physics), at the benchmark's budget."""
    from experiments import benchmark

    monkeypatch.chdir(tmp_path)
    assert benchmark.main(["--tasks", TASK, "--students", "sac", "--dry-run", "--no-calibrate"]) == 0
    cells = [line for line in capsys.readouterr().out.splitlines() if line.startswith("[")]
    assert len(cells) == 3 and all(f"--env={TASK}" in c and "--physics" not in c for c in cells), cells
    assert not os.listdir(tmp_path)


@pytest.mark.slow
def test_a_tiny_run_trains_from_the_command_line(tmp_path):
    """``python -m experiments.run --env=mountain_car_continuous`` with the tiny schedule (60-step episodes) and
    pink noise: it trains, evaluates and writes its summary on the JAX engine; its exported policy runs in
    gymnasium's env (``experiments.export``'s replay: 999-step episodes)."""
    from experiments.export import replay_in_gymnasium
    from tests.helpers import tiny_argv

    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "experiments.run", *tiny_argv("ddpg", env=TASK), "--noise=pink", "--steps=600",
           "--set", "run.buffer_size=600", "--out", str(out)]
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600,
                         env={**os.environ, "JAX_PLATFORMS": "cpu"})
    assert res.returncode == 0, res.stderr[-3000:]
    assert "final return" in res.stdout
    stored = json.loads((out / "config.json").read_text())["config"]
    assert stored["env"]["name"] == TASK and stored["env"]["physics"] == "mjx"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["env"] == TASK and len(summary["final_return_per_seed"]) == 2
    assert np.isfinite(summary["final_return_per_seed"]).all()
    rows = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    assert [r["env_steps"] for r in rows if r["seed"] == 0] == [300, 600]
    returns = replay_in_gymnasium(str(out / "policy.npz"), GYM_ID, seed=1, episodes=2)
    assert len(returns) == 2 and all(np.isfinite(r) and r <= 100 for r in returns)
