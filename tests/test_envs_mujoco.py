"""MJX ports of gymnasium's v5 MuJoCo tasks (envs/gym_mujoco.py).

The reference is gymnasium itself (``gymnasium.make('X-v5')``: MuJoCo C,
float64). Compiling an MJX step on CPU costs ~5-20 s per task, so each task
is compiled exactly once: ``_probe`` jits ONE function per task that builds
the initial states (reset noise and states copied from gymnasium) and scans
the vmapped step over a whole action sequence; one test per task
(``test_mjx_task``) then runs every check on its outputs.

Cross-check tolerances (float32 MJX vs float64 MuJoCo C), as
max |ours - gym| <= tol * max(1, max |gym|) per step, for observations,
rewards and the reward components in ``metrics``:
  IP, IDP, Reacher: 1e-5 over up to 20 steps (measured obs <= 1e-6);
  Hopper: 3e-5 over up to 30 steps (measured obs 4e-6, reward 1e-6);
  HalfCheetah: 1e-4 over 5 steps (chaotic: measured 8e-6 after 5 steps,
  ~1e-3 after 20).
Termination flags must match exactly at every step.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from envs.brax_mujoco import BRAX_TASKS
from envs.gym_mujoco import GYMNASIUM_TASKS, Hopper
from envs.mujoco_base import _mjx_solver, _while_loop_capped, state_from_qpos_qvel
from tests.helpers import gymnasium_make

# name -> (steps to scan, cross-check tolerance, rollout A must terminate)
CASES = {
    "inverted_pendulum": (20, 1e-5, True),
    "inverted_double_pendulum": (20, 1e-5, True),
    "hopper": (30, 3e-5, True),
    "halfcheetah": (5, 1e-4, False),
    "reacher": (20, 1e-5, False),
}
# Cross-check rollouts from gymnasium resets: A with full-range random
# actions (falls over on IP/IDP/Hopper, exercising termination), B with
# actions scaled by 0.1 (stays up longer, exercising the physics).
ROLLOUTS = (("A", 0, 1.0), ("B", 1, 0.1))  # (label, seed, action scale)
N_RESET = 3  # batch rows 0..2 start from env.reset; rows 3, 4 are A, B


def _gym_rollout(gym_id, seed, scale, n_steps):
    """Run gymnasium for n_steps (or until terminated) with random actions."""
    genv = gymnasium_make(gym_id)
    obs0, _ = genv.reset(seed=seed)
    data = genv.unwrapped.data
    qpos, qvel = data.qpos.copy(), data.qvel.copy()
    rng = np.random.default_rng(seed)
    actions = (scale * rng.uniform(-1, 1, (n_steps,) + genv.action_space.shape)).astype(np.float32)
    low, high = genv.action_space.low, genv.action_space.high
    steps = []
    for a in actions:
        gym_action = (low + (a + 1.0) * 0.5 * (high - low)).astype(np.float32)
        obs, rew, term, trunc, info = genv.step(gym_action)
        steps.append((obs, rew, term, info))
        if term:
            break
    genv.close()
    return dict(obs0=obs0, qpos=qpos, qvel=qvel, actions=actions, steps=steps,
                obs_shape=genv.observation_space.shape, act_shape=genv.action_space.shape,
                dt=genv.unwrapped.dt, frame_skip=genv.unwrapped.frame_skip)


@functools.lru_cache(maxsize=None)
def _probe(name):
    """Everything the tests need about one task, from a single jit."""
    n_steps = CASES[name][0]
    env = GYMNASIUM_TASKS[name]()
    gym = {label: _gym_rollout(env.gym_id, seed, scale, n_steps) for label, seed, scale in ROLLOUTS}

    keys = jax.random.split(jax.random.PRNGKey(42), 2)
    reset_keys = jnp.stack([keys[0], keys[1], keys[0]])  # row 2 repeats row 0's key
    rng = np.random.default_rng(7)
    bang = np.sign(rng.uniform(-1, 1, (n_steps, env.action_size))).astype(np.float32)
    actions = np.stack(
        [bang, rng.uniform(-1, 1, (n_steps, env.action_size)).astype(np.float32),
         3.0 * bang]  # out of range: clipping must make row 2 follow row 0
        + [gym[label]["actions"] for label, _, _ in ROLLOUTS],
        axis=1,
    )  # (T, batch, action_size)

    @jax.jit
    def run(reset_keys, qpos_x, qvel_x, actions):
        # env.reset is sample_qpos_qvel + state_from_qpos_qvel; going through
        # the two here lets the reset rows and the gymnasium-copied rows share
        # one forward pass in the compiled graph (it costs ~8 s on Hopper).
        qpos_r, qvel_r = jax.vmap(env.sample_qpos_qvel)(reset_keys)
        qpos = jnp.concatenate([qpos_r, qpos_x])
        qvel = jnp.concatenate([qvel_r, qvel_x])
        s0 = jax.vmap(functools.partial(state_from_qpos_qvel, env))(qpos, qvel)

        def body(s, a):
            s = jax.vmap(env.step)(s, a)
            return s, (s.obs, s.reward, s.done, s.metrics)

        s_final, traj = jax.lax.scan(body, s0, actions)
        return s0, s_final, traj

    qpos_x = np.stack([gym[label]["qpos"] for label, _, _ in ROLLOUTS])
    qvel_x = np.stack([gym[label]["qvel"] for label, _, _ in ROLLOUTS])
    # float32 matmuls as MuJoCo's C does them: under a GPU's default (TF32-class) precision HalfCheetah's
    # observation is off by 1.5e-4 after one step (measured on an H200; docs/gpu.md). A no-op on CPU.
    with jax.default_matmul_precision("highest"):
        s0, s_final, traj = jax.block_until_ready(run(reset_keys, qpos_x, qvel_x, actions))
    return dict(env=env, gym=gym, s0=s0, s_final=s_final, traj=traj, n_steps=n_steps, actions=actions)


def _dev(ours, ref):
    """max |ours - ref| / max(1, max |ref|)."""
    ref = np.asarray(ref, np.float64)
    return float(np.max(np.abs(np.asarray(ours, np.float64) - ref)) / max(1.0, np.max(np.abs(ref))))


def _check_matches_gymnasium(name, p):
    _, tol, must_terminate = CASES[name]
    obs_t, rew_t, done_t, metrics_t = jax.tree.map(np.asarray, p["traj"])
    worst = {"obs": 0.0, "reward": 0.0}
    for row, (label, _, _) in enumerate(ROLLOUTS, start=N_RESET):
        g = p["gym"][label]
        assert _dev(p["s0"].obs[row], g["obs0"]) <= tol, f"{label}: reset obs"
        for t, (obs, rew, term, info) in enumerate(g["steps"]):
            where = f"{name} rollout {label} step {t}"
            d_obs, d_rew = _dev(obs_t[t, row], obs), _dev(rew_t[t, row], rew)
            worst["obs"], worst["reward"] = max(worst["obs"], d_obs), max(worst["reward"], d_rew)
            assert d_obs <= tol, f"{where}: obs deviates {d_obs:.2e}"
            assert d_rew <= tol, f"{where}: reward deviates {d_rew:.2e}"
            assert done_t[t, row] == float(term), f"{where}: terminated {term} vs {done_t[t, row]}"
            for k, v in metrics_t.items():  # metric names follow gymnasium's info keys
                assert _dev(v[t, row], info[k]) <= tol, f"{where}: {k}"
        if label == "A" and must_terminate:
            assert g["steps"][-1][2], f"{name}: rollout A should fall within {p['n_steps']} steps"
        if label == "B":
            assert len(g["steps"]) >= 5, f"{name}: rollout B too short to test the physics"
    print(f"\n{name}: max relative deviation obs {worst['obs']:.2e}, reward {worst['reward']:.2e}")


def _check_mjx_and_the_c_engine_agree_to_float32_round_off(name, p):
    """The two engines (envs/mujoco_c.py) from the same gymnasium states with the same actions, step
    by step: observations and rewards within the float32 tolerances above, the same terminations."""
    from envs.mujoco_c import MujocoCEnv

    _, tol, _ = CASES[name]
    c_env = MujocoCEnv(p["env"])
    obs_t, rew_t, done_t, _ = jax.tree.map(np.asarray, p["traj"])
    for row, (label, _, _) in enumerate(ROLLOUTS, start=N_RESET):
        g = p["gym"][label]
        rows, obs = c_env.host.reset(g["qpos"][None], g["qvel"][None])
        assert _dev(p["s0"].obs[row], obs[0]) <= tol
        for t in range(len(g["steps"])):
            r = c_env.host.step(rows, g["actions"][t][None])
            rows, where = r["rows"], f"{name} rollout {label} step {t}"
            assert _dev(obs_t[t, row], r["next_obs"][0]) <= tol, where
            assert _dev(rew_t[t, row], r["reward"][0]) <= tol, where
            assert done_t[t, row] == float(r["terminated"][0]), where


def test_the_early_exit_loop_keeps_the_contract_of_mjxs_own_loop():
    """``_while_loop_capped`` (the loop MJX's line search runs while our step is traced) against MJX's own
    ``solver._while_loop_scan``, under ``vmap`` as in a batch of envs: rows whose condition fails at once,
    after a few iterations and never (stopped by the cap), on a pytree carry; the results are equal bit for
    bit. The whole-trajectory comparison with stock MJX on every task is ``python -m experiments.bench
    --env-speed --stock-mjx`` (a second MJX compile per task); the probes above check the physics against
    gymnasium and the C engine with the early exit on."""
    stock = _mjx_solver._while_loop_scan
    assert stock is not _while_loop_capped  # outside tracing our step, MJX's loop is its own

    def loop(impl, max_iter):
        def one(limit, x):
            cond = lambda v: v["x"] < limit
            body = lambda v: {"x": v["x"] * 1.01 + 0.3, "n": v["n"] + 1, "trace": v["trace"] + jnp.sin(v["x"])}
            return impl(cond, body, {"x": x, "n": jnp.zeros((), jnp.int32), "trace": jnp.zeros(3)}, max_iter)
        return jax.jit(jax.vmap(one))

    limits = jnp.asarray([-1.0, 1.0, 10.0, 1e9], jnp.float32)  # stops at once, after 3, after 30, never (the cap)
    starts = jnp.asarray([0.5, 0.1, -0.2, 1.0], jnp.float32)
    for max_iter in (1, 8, 50):
        want, got = loop(stock, max_iter)(limits, starts), loop(_while_loop_capped, max_iter)(limits, starts)
        for k in want:
            np.testing.assert_array_equal(np.asarray(got[k]), np.asarray(want[k]), err_msg=f"{k}, max_iter {max_iter}")
        assert int(want["n"][0]) == 0 and int(want["n"][-1]) == max_iter  # the cases the comment names happened
    assert int(want["n"][2]) > int(want["n"][1]) > 0  # (at max_iter 50) both stopped early, at different counts


def test_the_step_runs_its_line_search_through_the_early_exit_loop(monkeypatch):
    """Tracing a contact task's step calls ``_while_loop_capped`` (with ``early_exit_linesearch``, the
    default) and MJX's own loop without it; MJX's loop is back in place after either trace."""
    import envs.mujoco_base as base

    calls = []

    def counted(*args):
        calls.append(1)
        return _while_loop_capped(*args)

    monkeypatch.setattr(base, "_while_loop_capped", counted)
    stock = _mjx_solver._while_loop_scan
    for early_exit, expect_calls in ((True, True), (False, False)):
        calls.clear()
        env = GYMNASIUM_TASKS["hopper"](early_exit_linesearch=early_exit)
        state = jax.eval_shape(env.reset, jax.random.PRNGKey(0))
        jax.eval_shape(env.step, state, jnp.zeros(env.action_size))
        assert bool(calls) == expect_calls, early_exit
        assert _mjx_solver._while_loop_scan is stock


def _check_shapes_dtypes_and_structure(name, p):
    env, g = p["env"], p["gym"]["A"]
    assert env.observation_size == g["obs_shape"][0]
    assert env.action_size == g["act_shape"][0]
    assert env.backend == "mjx"
    assert env.frame_skip == g["frame_skip"]
    assert env.dt == pytest.approx(g["dt"])
    assert isinstance(env.observation_size, int) and isinstance(env.action_size, int)

    s0, s_final = p["s0"], p["s_final"]
    batch, T = N_RESET + len(ROLLOUTS), p["n_steps"]
    assert s0.obs.shape == (batch, env.observation_size) and s0.obs.dtype == jnp.float32
    assert s0.reward.dtype == jnp.float32 and s0.done.dtype == jnp.float32
    assert not np.any(s0.reward) and not np.any(s0.done)
    assert s0.info == {}
    # Reset and step states must have identical pytree structure and leaf
    # avals, or lax.scan / lax.cond over them would fail.
    avals = lambda s: jax.tree.map(lambda x: (x.shape, x.dtype), s)
    assert avals(s0) == avals(s_final)
    leaves = [x for x in jax.tree.leaves(s_final) if jnp.issubdtype(x.dtype, jnp.floating)]
    assert all(x.dtype == jnp.float32 for x in leaves), "float64 leaked in"

    obs, rew, done, metrics = p["traj"]
    assert obs.shape == (T, batch, env.observation_size)
    assert rew.shape == done.shape == (T, batch)
    assert obs.dtype == rew.dtype == done.dtype == jnp.float32
    assert set(np.unique(np.asarray(done))) <= {0.0, 1.0}
    for m in metrics.values():
        assert m.shape == (T, batch) and m.dtype == jnp.float32
    # The reset rows (random and bang-bang actions) stay finite; we step on
    # past termination there, as a batched learner between resets does.
    assert np.all(np.isfinite(np.asarray(obs[:, :N_RESET])))
    # Actions are clipped to [-1, 1]: row 2 (same key, 3x row 0's +-1 actions)
    # retraces row 0 exactly.
    np.testing.assert_array_equal(obs[:, 2], obs[:, 0])


def _check_reset_noise(name, p):
    env, s0 = p["env"], p["s0"]
    qpos0 = np.asarray(s0.pipeline_state.qpos)
    np.testing.assert_array_equal(qpos0[0], qpos0[2])  # same key, same state
    assert np.any(qpos0[0] != qpos0[1])  # other key, other state
    assert np.any(np.asarray(s0.pipeline_state.qvel)[0] != np.asarray(s0.pipeline_state.qvel)[1])

    # Noise distribution from many keys; cheap to compile (no physics).
    keys = jax.random.split(jax.random.PRNGKey(3), 2048)
    qpos, qvel = jax.jit(jax.vmap(env.sample_qpos_qvel))(keys)
    dq = np.asarray(qpos) - np.asarray(env.init_qpos)
    dv = np.asarray(qvel) - np.asarray(env.init_qvel)

    def uniform(x, s):  # within gymnasium's bounds and filling them
        assert np.all(np.abs(x) <= s) and np.all(np.abs(x).max(0) > 0.95 * s)
        np.testing.assert_allclose(x.std(0), s / np.sqrt(3), rtol=0.1)

    def normal(x, s):
        np.testing.assert_allclose(x.std(0), s, rtol=0.1)
        assert np.all(np.abs(x) < 6 * s)

    if name == "reacher":  # reacher_v5.reset_model
        uniform(dq[:, :2], 0.1)
        goal = np.asarray(qpos)[:, 2:]
        radius = np.linalg.norm(goal, axis=1)
        assert np.all(radius < 0.2) and radius.max() > 0.19
        # uniform on the disc: P(r < 0.1) = 1/4
        assert abs(np.mean(radius < 0.1) - 0.25) < 0.04
        uniform(dv[:, :2], 0.005)
        assert np.all(dv[:, 2:] == 0)
    else:
        s = env._reset_noise_scale
        uniform(dq, s)
        if name in ("inverted_double_pendulum", "halfcheetah"):
            normal(dv, s)
        else:
            uniform(dv, s)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(CASES))
def test_mjx_task(name):
    """Every check of one task on its probe. One test per task, not one per check: xdist hands consecutive
    tests to alternate workers, and each worker running a check of a task would compile (or trace, from the
    session's cache) that task's MJX program again."""
    p = _probe(name)
    _check_matches_gymnasium(name, p)
    _check_mjx_and_the_c_engine_agree_to_float32_round_off(name, p)
    _check_shapes_dtypes_and_structure(name, p)
    _check_reset_noise(name, p)


def test_hopper_health_matches_gymnasium():
    """Hopper's is_healthy (termination) on states on both sides of each range."""
    env = Hopper()
    genv = gymnasium_make("Hopper-v5").unwrapped
    genv.reset(seed=0)
    base_q, base_v = genv.init_qpos.copy(), genv.init_qvel.copy()
    cases = [
        ({}, {}),
        ({1: 0.71}, {}), ({1: 0.69}, {}),          # torso height z
        ({2: 0.19}, {}), ({2: 0.21}, {}), ({2: -0.21}, {}),  # torso angle
        ({3: 99.0}, {}), ({}, {4: 101.0}), ({}, {0: 500.0}),  # state range (from index 2)
    ]
    for dq, dv in cases:
        q, v = base_q.copy(), base_v.copy()
        for i, x in dq.items():
            q[i] = x
        for i, x in dv.items():
            v[i] = x
        genv.set_state(q, v)

        class Data:  # is_healthy only reads qpos and qvel
            qpos, qvel = jnp.asarray(q, jnp.float32), jnp.asarray(v, jnp.float32)

        assert bool(env.is_healthy(Data)) == genv.is_healthy, (dq, dv)


@pytest.mark.slow
def test_brax_tasks_build_and_step(tmp_path, monkeypatch):
    """All five of brax's versions build on mjx (and write no MUJOCO_LOG.TXT into the working directory:
    brax's half_cheetah.xml has the deprecated settotalmass too); one is stepped under jit+vmap."""
    assert set(BRAX_TASKS) == set(GYMNASIUM_TASKS)
    monkeypatch.chdir(tmp_path)
    for name in BRAX_TASKS:
        env = BRAX_TASKS[name]()
        assert env.backend == "mjx" and env.action_size >= 1
    assert list(tmp_path.iterdir()) == []

    env = BRAX_TASKS["inverted_pendulum"]()

    @jax.jit
    def run(keys):
        s0 = jax.vmap(env.reset)(keys)
        s1 = jax.vmap(env.step)(s0, jnp.full((keys.shape[0], env.action_size), 5.0))
        return s0, s1

    s0, s1 = run(jax.random.split(jax.random.PRNGKey(0), 2))
    assert s0.obs.shape == (2, env.observation_size) == (2, 4)
    assert s0.info == {} and s1.info == {}
    assert s1.reward.dtype == s1.done.dtype == jnp.float32
    assert jax.tree.structure(s0) == jax.tree.structure(s1)
    assert np.all(np.isfinite(np.asarray(s1.obs)))
    # a clipped push to the right accelerates the cart to the right
    assert np.all(np.asarray(s1.obs)[:, 2] > 0)


def test_halfcheetah_model_loads_without_the_settotalmass_warning(tmp_path, monkeypatch):
    """envs.mujoco_base.load_model compiles HalfCheetah's XML without its deprecated ``settotalmass``
    attribute (mj_setTotalmass + mj_setConst instead): every array of the model equals the one compiled
    from the file as it is, and nothing lands in the working directory (MuJoCo's MUJOCO_LOG.TXT)."""
    import mujoco

    from envs.mujoco_base import gymnasium_asset_path, load_model

    path = gymnasium_asset_path("half_cheetah.xml")
    assert 'settotalmass="14"' in open(path).read()  # the case load_model handles is still there
    ours_dir, reference_dir = tmp_path / "ours", tmp_path / "reference"
    ours_dir.mkdir()
    reference_dir.mkdir()
    monkeypatch.chdir(ours_dir)
    ours = load_model(path)
    import envs

    envs.make("halfcheetah", physics="mujoco")  # the C engine's env, as a run builds it
    assert list(ours_dir.iterdir()) == []
    monkeypatch.chdir(reference_dir)
    reference = mujoco.MjModel.from_xml_path(path)  # MuJoCo warns here (into reference_dir)
    compared = 0
    for name in dir(reference):
        value = getattr(reference, name, None)
        if not name.startswith("_") and isinstance(value, np.ndarray):
            np.testing.assert_array_equal(getattr(ours, name), value, err_msg=name)
            compared += 1
    assert compared > 100 and ours.body_mass.sum() == pytest.approx(14.0)
