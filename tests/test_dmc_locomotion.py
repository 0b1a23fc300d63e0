"""DeepMind Control suite's finger, hopper, walker and cheetah (envs/dmc_finger.py, envs/dmc_locomotion.py):
what tests/test_dmc.py's whole-episode comparison with dm_control does not show on its own. The touch sensors are
the last substep's, the velocity sensors the new state's; cheetah's reset settles its draw as dm_control's does,
to the bit; each task's reward reaches its top; MJX stays near the C engine."""

from __future__ import annotations

import os
import types

import jax
import mujoco
import numpy as np
import pytest

import envs

os.environ.setdefault("MUJOCO_GL", "disable")
suite = pytest.importorskip("dm_control.suite")


def _rows(raw, qpos, qvel, params=()):
    """A C-engine state row (integration state, model params) at qpos/qvel, without the reset's rules."""
    m = raw.mj_model
    data = mujoco.MjData(m)
    data.qpos[:], data.qvel[:] = qpos, qvel
    row = np.empty(raw.host.nstate)
    mujoco.mj_getState(m, data, row, mujoco.mjtState.mjSTATE_INTEGRATION)
    return np.concatenate([row, np.asarray(params, np.float64)])[None]


def test_touch_sensors_are_the_last_substeps_and_velocity_sensors_the_new_states():
    """hopper-hop on the host, 200 steps of random actions: the touch sensors equal those of a plain mj_step loop
    (acceleration stage: computed by the last substep, at the state before it), which at some steps differ from
    the new state's; the speed (subtree linear velocity) is the new state's, as after mj_forward."""
    raw = envs.make_raw("dmc:hopper-hop", physics="mujoco")
    host, m = raw.host, raw.mj_model
    touch = [m.sensor_adr[raw.task._id("sensor", n)] for n in ("touch_toe", "touch_heel")]
    speed = m.sensor_adr[raw.task._id("sensor", "torso_subtreelinvel")]
    qpos = m.qpos0.copy()
    qpos[1] = 0.3  # upright, feet in the air: it lands
    rows, _ = host.reset(qpos[None], np.zeros((1, m.nv)))
    data = mujoco.MjData(m)
    actions = np.random.default_rng(0).uniform(-1, 1, (200, 1, host.nu)).astype(np.float32)
    touched = differs = 0
    speeds = []
    for t in range(len(actions)):
        mujoco.mj_setState(m, data, rows[0, :host.nstate], mujoco.mjtState.mjSTATE_INTEGRATION)
        r = host.step(rows, actions[t])
        data.ctrl[:] = r["ctrl"][0]
        mujoco.mj_step(m, data, raw.frame_skip)
        np.testing.assert_array_equal(r["next_obs"][0, -2:], np.log1p(data.sensordata[touch]), err_msg=f"step {t}")
        last_substeps = data.sensordata[touch].copy()
        mujoco.mj_forward(m, data)
        new_state = types.SimpleNamespace(xipos=data.xipos[None], sensordata=data.sensordata[None])
        assert r["reward"][0] == raw.task._reward(np, new_state, r["ctrl"])[0], f"step {t}"
        speeds.append(data.sensordata[speed])
        touched += last_substeps.any()
        differs += not np.array_equal(last_substeps, data.sensordata[touch])
        rows = r["rows"]
    assert touched > 20 and differs > 0, (touched, differs)
    assert max(speeds) > 0.1 and min(speeds) < -0.1  # the reward's speed term was exercised


def test_cheetah_settles_its_draw_as_dm_control():
    """From dm_control's draw (its first from RandomState(seed)), our reset's 200 settling steps give dm_control's
    whole integration state after its reset (qpos, qvel, the solver's warm start, time 0), bit for bit."""
    raw = envs.make_raw("dmc:cheetah-run", physics="mujoco")
    m = raw.mj_model
    limited = m.jnt_limited == 1
    for seed in range(3):
        dm = suite.load("cheetah", "run", task_kwargs={"random": seed})
        dm.reset()
        expected = np.empty(raw.host.nstate)
        mujoco.mj_getState(dm.physics.model.ptr, dm.physics.data.ptr, expected, mujoco.mjtState.mjSTATE_INTEGRATION)
        qpos = m.qpos0.copy()
        qpos[limited] = np.random.RandomState(seed).uniform(*m.jnt_range[limited].T)
        rows, _ = raw.host.reset(qpos[None], np.zeros((1, m.nv)))
        np.testing.assert_array_equal(rows[0], expected)
        assert np.abs(expected[1:1 + m.nq] - qpos).max() > 0.01  # it moved


# name, qpos (None: qpos0), qvel entries, model params
_TOP = [
    ("finger-spin", [-1.5, 0.0, 0.5], {2: -20.0}, ()),  # the spinner turning at -20 rad/s
    ("finger-turn_hard", [-1.5, 0.0, 0.5], {}, None),  # the target at the tip (params below)
    ("hopper-stand", None, {}, ()),  # upright, zero controls
    ("hopper-hop", None, {0: 3.0}, ()),  # upright, moving forward at 3 m/s
    ("walker-walk", None, {1: 1.5}, ()),
    ("walker-run", None, {1: 9.0}, ()),
    ("cheetah-run", [0.0, 0.3], {0: 12.0}, ()),  # in the air, 12 m/s forward
]


@pytest.mark.parametrize("name, qpos, qvel, params", _TOP)
def test_rewards_reach_their_top(name, qpos, qvel, params):
    """One host step with zero action from a scripted state pays (nearly) 1: finger-spin's sparse spin,
    finger-turn's sparse target touch, hopper-stand's standing term, and the speed terms of hopper-hop,
    walker-walk / run and cheetah-run."""
    raw = envs.make_raw(f"dmc:{name}", physics="mujoco")
    m = raw.mj_model
    q = m.qpos0.copy()
    q[:len(qpos or ())] = qpos or ()
    v = np.zeros(m.nv)
    for k, x in qvel.items():
        v[k] = x
    if params is None:
        data = mujoco.MjData(m)
        data.qpos[:] = q
        mujoco.mj_forward(m, data)
        tip = data.site_xpos[raw.task._id("site", "tip")]
        params = (tip[0], tip[2])
    r = raw.host.step(_rows(raw, q, v, params), np.zeros((1, m.nu), np.float32))
    assert r["reward"][0] >= 0.999, r["reward"]


def test_sizes_and_control_steps():
    sizes = {"finger-spin": (9, 2, 2), "finger-turn_hard": (12, 2, 2), "hopper-hop": (15, 4, 4),
             "walker-walk": (24, 6, 10), "cheetah-run": (17, 6, 1)}
    for name, (obs, act, frame_skip) in sizes.items():
        env = envs.make_raw(f"dmc:{name}", physics="mujoco")
        assert (env.observation_size, env.action_size, env.frame_skip) == (obs, act, frame_skip), name
    assert envs.get_spec("dmc:walker-run").episode_length == 1000


@pytest.mark.slow
def test_mjx_stays_near_the_c_engine_on_hopper():
    """MJX (float32) against the C engine from the same reset, 50 steps of random actions on hopper-hop:
    observations within 5e-5 for 10 steps and 1e-2 for 50 (measured 4e-6 and 1e-4; over two envs and 100 steps
    6e-6, 7e-4 at 50 and 1.5e-2: they grow once the feet touch the floor, as fast as the C engine's own from a
    start moved by 1e-6), rewards within 1e-6 (measured 0)."""
    c = envs.make_raw("dmc:hopper-hop", physics="mujoco")
    m = envs.make_raw("dmc:hopper-hop", physics="mjx")
    actions = jax.random.uniform(jax.random.PRNGKey(4), (50, c.action_size), minval=-1.0, maxval=1.0)

    def run(env):
        def body(s, a):
            s = env.step(s, a)
            return s, (s.obs, s.reward)
        return jax.jit(lambda k: jax.lax.scan(body, env.reset(k), actions)[1])(jax.random.PRNGKey(3))

    (obs_m, rew_m), (obs_c, rew_c) = jax.tree.map(np.asarray, (run(m), run(c)))
    np.testing.assert_allclose(obs_m[:10], obs_c[:10], rtol=0, atol=5e-5)
    np.testing.assert_allclose(obs_m, obs_c, rtol=0, atol=1e-2)
    np.testing.assert_allclose(rew_m, rew_c, rtol=0, atol=1e-6)
    assert (obs_c[:, -2:] > 0).any()  # the feet touched the floor
