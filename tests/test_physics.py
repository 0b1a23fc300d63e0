"""MuJoCo's C engine inside the program (envs/mujoco_c.py, ``--physics=mujoco``).

The reference is gymnasium itself (``gymnasium.make('X-v5')``, MuJoCo's C engine in float64):
from the same initial state and the same actions, our observations, rewards, reward components,
terminated/truncated flags and the complete integration state must equal gymnasium's bit for bit,
on the host (float64) and through the compiled program (float32 casts of the same numbers).
A C-engine program compiles without MJX's physics (a host call instead), so these tests are cheap; a
training program costs what the same program on the JAX Pendulum costs.
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
from envs.gym_mujoco import GYMNASIUM_TASKS
from envs.mujoco_c import STATE_SPEC, HostPhysics, MujocoCEnv
from tests.helpers import gymnasium_make, sigkill_resume_and_compare, tiny_argv

# task -> (gymnasium id, steps of one whole episode: gymnasium's time limit)
TASKS = {
    "inverted_pendulum": ("InvertedPendulum-v5", 1000),
    "inverted_double_pendulum": ("InvertedDoublePendulum-v5", 1000),
    "hopper": ("Hopper-v5", 1000),
    "halfcheetah": ("HalfCheetah-v5", 1000),
    "reacher": ("Reacher-v5", 50),
}
# Two envs per batch: full-range random actions (falls at once on IP/IDP/Hopper, exercising
# termination, contacts and joint limits) and actions scaled by 0.1 (stays up longer).
SCALES = (1.0, 0.1)


def _gym_state(data) -> np.ndarray:
    state = np.empty(mujoco.mj_stateSize(data.model, STATE_SPEC))
    mujoco.mj_getState(data.model, data, state, STATE_SPEC)
    return state


@pytest.fixture(scope="module", params=list(TASKS))
def c_env(request):
    name = request.param
    return name, MujocoCEnv(GYMNASIUM_TASKS[name]())


def _actions(env, steps, seed=0):
    rng = np.random.default_rng(seed)
    a = rng.uniform(-1, 1, (steps, len(SCALES), env.action_size)) * np.array(SCALES)[None, :, None]
    return a.astype(np.float32)


def _ctrl(env, actions):
    """The float64 controls our step applies (the action clipped, mapped onto ctrlrange on the host)."""
    return env.task.scale_action(np.clip(actions, -1.0, 1.0), np)


def test_host_steps_equal_gymnasium_bit_for_bit_for_a_whole_episode(c_env):
    """Both envs step on for the whole episode length, past a termination (as gymnasium's unwrapped
    env and a batched learner between resets do): obs, reward, reward components, terminated and
    the integration state (warm start included) equal gymnasium's at every step."""
    name, env = c_env
    gym_id, steps = TASKS[name]
    gyms = [gymnasium_make(gym_id).unwrapped for _ in SCALES]
    obs0 = [g.reset(seed=10 + i)[0] for i, g in enumerate(gyms)]
    rows, obs = env.host.reset(np.stack([g.data.qpos for g in gyms]), np.stack([g.data.qvel for g in gyms]))
    np.testing.assert_array_equal(obs, np.stack(obs0))
    np.testing.assert_array_equal(rows, np.stack([_gym_state(g.data) for g in gyms]))
    actions = _actions(env, steps)
    ctrl = _ctrl(env, actions)
    terminated_any = False
    for t in range(steps):
        r = env.host.step(rows, actions[t])
        np.testing.assert_array_equal(r["ctrl"], ctrl[t])
        for i, g in enumerate(gyms):
            g_obs, g_rew, g_term, _, g_info = g.step(ctrl[t, i])
            where = f"{name} env {i} step {t}"
            assert r["next_obs"].dtype == np.float64
            np.testing.assert_array_equal(r["next_obs"][i], g_obs, err_msg=where)
            assert r["reward"][i] == g_rew, where
            assert bool(r["terminated"][i]) == g_term, where
            for k, v in r["metrics"].items():
                assert v[i] == g_info[k], f"{where}: {k}"
            np.testing.assert_array_equal(r["rows"][i], _gym_state(g.data), err_msg=where)
            terminated_any |= g_term
        rows = r["rows"]
    if name in ("inverted_pendulum", "inverted_double_pendulum", "hopper"):
        assert terminated_any, f"{name}: the random actions should end an episode"
    assert np.ptp(rows[:, 1:1 + env.host.nq]) > 0.1  # the physics moved


def _wrapped_start(wrapped, raw_state, key):
    """A wrapped (time limit, auto-reset) state whose physics is ``raw_state``'s."""
    s = wrapped.reset(key)
    return s.replace(pipeline_state=raw_state.pipeline_state, obs=raw_state.obs,
                     info={**s.info, "next_obs": raw_state.obs})


def test_the_compiled_program_gives_gymnasiums_episode(c_env):
    """envs.make(..., physics='mujoco') in jit + vmap from gymnasium's reset states, to the end of
    gymnasium's episode (TimeLimit included): float32 obs, rewards and flags are gymnasium's numbers
    cast; the auto-reset afterwards is gymnasium's reset at the sampled qpos/qvel."""
    name, _ = c_env
    gym_id, steps = TASKS[name]
    wrapped = envs.make(name, physics="mujoco")
    raw = wrapped.unwrapped
    gyms = [gymnasium_make(gym_id) for _ in SCALES]
    for i, g in enumerate(gyms):
        g.reset(seed=20 + i)
    qpos = np.stack([g.unwrapped.data.qpos for g in gyms])
    qvel = np.stack([g.unwrapped.data.qvel for g in gyms])
    start = jax.vmap(lambda raw_state, key: _wrapped_start(wrapped, raw_state, key))(
        raw.state_from_gymnasium(qpos, qvel), jax.random.split(jax.random.PRNGKey(0), len(SCALES)))
    actions = _actions(raw, steps, seed=1)

    @jax.jit
    def run(s, actions):
        def body(s, a):
            s = jax.vmap(wrapped.step)(s, a)
            return s, (s.info["next_obs"], s.reward, s.info["terminated"], s.info["truncated"], s.obs,
                       s.pipeline_state)
        return jax.lax.scan(body, s, actions)

    _, (next_obs, reward, term, trunc, obs, words) = jax.tree.map(np.asarray, run(start, actions))
    ctrl = _ctrl(raw, actions)
    for i, g in enumerate(gyms):
        for t in range(steps):
            g_obs, g_rew, g_term, g_trunc, _ = g.step(ctrl[t, i])
            where = f"{name} env {i} step {t}"
            np.testing.assert_array_equal(next_obs[t, i], g_obs.astype(np.float32), err_msg=where)
            assert reward[t, i] == np.float32(g_rew), where
            assert (term[t, i], trunc[t, i]) == (float(g_term), float(g_trunc)), where
            if g_term or g_trunc:
                break
        assert g_term or g_trunc
        # The next episode: gymnasium's reset (mj_resetData, qpos/qvel, mj_forward) of the drawn state.
        rows = words[t, i].view(np.float64)
        nq, nv = raw.host.nq, raw.host.nv
        assert rows[0] == 0.0  # the integration state starts with the time
        g.reset()
        g.unwrapped.set_state(rows[1:1 + nq], rows[1 + nq:1 + nq + nv])
        np.testing.assert_array_equal(rows, _gym_state(g.unwrapped.data), err_msg=f"{name} env {i}: reset")
        np.testing.assert_array_equal(obs[t, i], g.unwrapped._get_obs().astype(np.float32))


def test_the_vmapped_callback_gets_the_whole_batch_in_one_call(monkeypatch):
    raw = envs.make_raw("inverted_double_pendulum", physics="mujoco")
    calls = []
    step_words = raw.host.step_words
    monkeypatch.setattr(raw.host, "step_words", lambda w, fused: calls.append(np.shape(w)) or step_words(w, fused))
    seeds, per_seed, steps = 3, 2, 4
    keys = jax.random.split(jax.random.PRNGKey(0), seeds * per_seed).reshape(seeds, per_seed, 2)

    @jax.jit
    def run(keys):
        s = jax.vmap(jax.vmap(raw.reset))(keys)
        def body(s, _):
            return jax.vmap(jax.vmap(raw.step))(s, jnp.zeros((seeds, per_seed, 1))), None
        return jax.lax.scan(body, s, None, length=steps)[0]

    out = run(keys)
    assert calls == [(seeds, per_seed, raw.host.w_state + 1)] * steps
    assert out.obs.shape == (seeds, per_seed, raw.observation_size)


def sharded_steps() -> dict:
    """Reset and 6 steps of 4 seeds x 3 Hopper envs on the C engine with the seed axis sharded over every device,
    as ``experiments.run`` shards it (``metapg_jax/host/driver.py``): the trajectory, the device count and the
    shapes the host's step got."""
    from jax.sharding import Mesh, NamedSharding, PartitionSpec

    raw = envs.make_raw("hopper", physics="mujoco")
    shapes = []
    step_words = raw.host.step_words
    raw.host.step_words = lambda w, fused: shapes.append(np.shape(w)) or step_words(w, fused)
    mesh = Mesh(np.array(jax.devices()), ("seeds",))
    seeds, time_seeds = NamedSharding(mesh, PartitionSpec("seeds")), NamedSharding(mesh, PartitionSpec(None, "seeds"))
    keys = jax.random.split(jax.random.PRNGKey(0), 12).reshape(4, 3, 2)
    actions = jax.random.uniform(jax.random.PRNGKey(1), (6, 4, 3, raw.action_size), minval=-1.0, maxval=1.0)

    def run(keys, actions):
        def body(s, a):
            s = jax.vmap(jax.vmap(raw.step))(s, a)
            return s, (s.obs, s.reward, s.pipeline_state)
        return jax.lax.scan(body, jax.vmap(jax.vmap(raw.reset))(keys), actions)[1]

    run = jax.jit(run, in_shardings=(seeds, time_seeds), out_shardings=time_seeds)
    obs, reward, words = jax.device_get(run(jax.device_put(keys, seeds), jax.device_put(actions, time_seeds)))
    return {"obs": obs, "reward": reward, "words": words, "devices": jax.device_count(), "shapes": np.array(shapes)}


def test_the_host_call_gets_the_whole_batch_once_with_the_seed_axis_sharded(tmp_path):
    """Two CPU devices, each holding two seeds (a subprocess: the device count is fixed at JAX's start): the host
    steps all 12 envs in one call per step (on one device), and the numbers are one device's bit for bit."""
    import subprocess
    import sys

    from tests import xla_flags

    path = str(tmp_path / "two.npz")
    code = f"import numpy as np; from tests.test_physics import sharded_steps; np.savez({path!r}, **sharded_steps())"
    env = {**os.environ, "XLA_FLAGS": xla_flags("--xla_force_host_platform_device_count=2")}
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    out = subprocess.run([sys.executable, "-c", code], cwd=root, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    one, two = sharded_steps(), dict(np.load(path))
    assert (one["devices"], int(two["devices"])) == (1, 2)
    w_in = envs.make_raw("hopper", physics="mujoco").host.w_state + 3
    for r in (one, two):
        assert r["shapes"].tolist() == [[4, 3, w_in]] * 6
    for k in ("obs", "reward", "words"):
        np.testing.assert_array_equal(one[k], two[k], err_msg=k)


def test_engines_refuse_what_they_cannot_run():
    with pytest.raises(ValueError, match="unknown physics 'bullet'; valid physics: auto, mjx, mujoco"):
        envs.make("hopper", physics="bullet")
    with pytest.raises(ValueError, match="source 'brax' has only MJX"):
        envs.make("hopper", source="brax", physics="mujoco")
    with pytest.raises(ValueError, match="pendulum is a JAX task"):
        envs.make("pendulum", physics="mujoco")
    with pytest.raises(ValueError, match="physics threads must be a whole number >= 1, got 0"):
        HostPhysics(GYMNASIUM_TASKS["reacher"](), threads=0)


def test_threads_step_the_batch_to_the_numbers_of_one_thread(monkeypatch):
    """MuJoCo's batch on 1, 2 and 3 threads from the same rows, actions and resets (Hopper, 7 envs, 150 steps
    with terminations, forced resets and the fused auto-reset): every output bit for bit the same. A bad
    $METAPG_PHYSICS_THREADS (what --physics-threads sets) is refused in one line; a good one is the default."""
    from envs.host_call import THREADS_VARIABLE, default_threads

    task, n, steps = GYMNASIUM_TASKS["hopper"](), 7, 150
    hosts = [HostPhysics(task, threads=k) for k in (1, 2, 3)]
    rng = np.random.default_rng(5)
    qpos0 = np.asarray(task.init_qpos, np.float64)[None] + rng.uniform(-0.005, 0.005, (n, task.mj_model.nq))
    outs = [h.reset(qpos0, np.zeros((n, task.mj_model.nv))) for h in hosts]
    for r in outs[1:]:
        np.testing.assert_array_equal(r[0], outs[0][0])
    rows = [r[0] for r in outs]
    ended = 0
    for t in range(steps):
        a = rng.uniform(-1, 1, (n, task.action_size))
        reset_q = np.asarray(task.init_qpos, np.float64)[None] + rng.uniform(-0.005, 0.005, (n, task.mj_model.nq))
        reset_v = rng.uniform(-0.005, 0.005, (n, task.mj_model.nv))
        tries = np.concatenate([reset_q, reset_v], axis=-1)[:, None]  # one reset candidate per env
        force = rng.uniform(size=n) < 0.02
        res = [h.step(r, a, tries, force) for h, r in zip(hosts, rows)]
        for r in res[1:]:
            for k in ("rows", "obs", "next_obs", "reward", "terminated"):
                np.testing.assert_array_equal(r[k], res[0][k], err_msg=f"{k} at step {t}")
        ended += int((res[0]["terminated"] | force).sum())
        rows = [r["rows"] for r in res]
    assert ended > 0
    monkeypatch.setenv(THREADS_VARIABLE, "3")
    assert default_threads() == 3 and HostPhysics(task).threads == 3
    monkeypatch.setenv(THREADS_VARIABLE, "-2")
    with pytest.raises(ValueError, match="METAPG_PHYSICS_THREADS=must be a whole number >= 1, got '-2'"):
        HostPhysics(task)


@pytest.mark.parametrize("argv, message", [
    (["--env=hopper", "--physics=mujoco", "--source=brax"], "error: --physics=mujoco steps gymnasium's models"),
    (["--env=hopper", "--physics=warp"], "error: unknown physics 'warp'; valid physics: auto, mjx, mujoco"),
])
def test_cli_refuses_bad_physics_before_compiling(argv, message, tmp_path, capsys):
    from tests.helpers import assert_run_refuses

    assert_run_refuses(argv, message, tmp_path, capsys)


# -- training with the C engine: resume after SIGKILL, a smoke test per task (deterministic and chunked ==
# single scan: tests/test_train.py) ----------------------------------------------------------------------

# DDPG (a smaller program than Meta's, whose C-engine runs test_train.py and the tiny run per task below
# cover): the C engine's state in checkpoints and a resume bit for bit.
TINY_IP = [*tiny_argv("ddpg", env="inverted_pendulum"), "--physics=mujoco", "--checkpoint-every=1"]


@pytest.mark.slow
def test_c_engine_run_resumes_bit_for_bit_after_sigkill(tmp_path):
    # Two physics threads, resumed on one: the thread count is not part of the run and changes no number.
    full = sigkill_resume_and_compare(tmp_path, TINY_IP + ["--steps=1800", "--physics-threads=2"], chunks=6,
                                      resume_args=["--physics-threads=1"])
    summary = json.load(open(os.path.join(full, "summary.json")))
    assert summary["physics"] == "mujoco"


# Inverted Double Pendulum trains Meta and DDPG on the C engine in tests/test_train.py and tests/test_golden.py,
# Inverted Pendulum DDPG above; the training program is the same for every task but for the env's sizes, and
# Meta's cycle steps the env through the same calls as DDPG's (reset, step; on the C engine one host call per
# step), so the other tasks train DDPG, a smaller program. (The fast tier, -m "not slow", trains Reacher's.)
@pytest.mark.parametrize("task", [pytest.param("hopper", marks=pytest.mark.slow),
                                  pytest.param("halfcheetah", marks=pytest.mark.slow), "reacher"])
def test_the_other_mujoco_tasks_train_a_tiny_ddpg_run_on_the_c_engine(task):
    """A smoke test per task: one compiled program, finite state, the student updated."""
    import chex

    from metapg_jax.train import make_train, seed_keys, vmap_seeds
    from tests.helpers import tiny_config

    cfg = tiny_config("ddpg", steps=300, env=task, physics="mujoco", **{"env.episode_length": 50})
    state, metrics = jax.jit(vmap_seeds(make_train(cfg).train))(seed_keys(0, 2))
    chex.assert_tree_all_finite(state.student)
    assert np.isfinite(np.asarray(metrics["eval_return"])).all()
    assert np.asarray(metrics["cycle"]["finite"]).all()
    assert int(state.env_steps[0]) == 300 and int(state.updates[0]) > 0


def test_auto_physics_is_the_c_engine_on_a_cpu_and_mjx_elsewhere():
    """``physics='auto'`` (the command lines' default): MuJoCo's C engine for gymnasium's MuJoCo tasks where
    JAX runs on the CPU; MJX on accelerators and for brax's models; Pendulum keeps 'mjx' (JAX physics)."""
    from metapg_jax.config import make_config

    assert jax.default_backend() == "cpu"
    for task in TASKS:
        assert envs.resolve_physics(task, "gymnasium", "auto") == "mujoco"
        assert make_config(task, "meta", physics="auto").env.physics == "mujoco"
        assert envs.resolve_physics(task, "gymnasium", "auto", backend="gpu") == "mjx"
        assert envs.resolve_physics(task, "brax", "auto") == "mjx"
        for explicit in envs.PHYSICS:
            assert envs.resolve_physics(task, "gymnasium", explicit) == explicit
    assert envs.resolve_physics("pendulum", "gymnasium", "auto") == "mjx"
    assert type(envs.make("reacher", physics="auto").unwrapped).__name__ == "MujocoCEnv"
