"""TD3 (metapg_jax/strategies/td3.py): the clipped double-Q target, target smoothing, delayed actor and target
updates, and TD3 as the student of both explorers and of the command line."""

import json
import os

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from metapg_jax.config import DDPGConfig, make_config
from metapg_jax.strategies.td3 import TD3, TD3Config
from tests.helpers import tiny_argv
from metapg_jax.train import make_train, seed_keys, vmap_seeds
from metapg_jax.types import Transition
from tests import golden


def _student(**td3):
    return TD3(DDPGConfig(hidden=(8, 8), layer_norm=False, critic_action_layer=0, critic_l2=0.0,
                          normalize_obs=False), obs_size=3, action_size=2, td3=TD3Config(**td3))


def _batch(n=5, seed=0):
    k = jax.random.split(jax.random.PRNGKey(seed), 4)
    return Transition(obs=jax.random.normal(k[0], (n, 3)), action=jax.random.uniform(k[1], (n, 2), minval=-1, maxval=1),
                      reward=jax.random.normal(k[2], (n,)), next_obs=jax.random.normal(k[3], (n, 3)),
                      terminated=jnp.array([0, 1, 0, 0, 1], jnp.float32)[:n], truncated=jnp.zeros((n,)))


def test_target_is_the_minimum_of_the_two_target_critics_without_bootstrap_at_termination():
    td3 = _student(policy_noise=0.0)
    state = td3.init(jax.random.PRNGKey(1))
    state = state.replace(target_critic={"q1": state.critic["q1"], "q2": td3.init(jax.random.PRNGKey(2)).critic["q2"]})
    batch = _batch()
    target = np.asarray(td3.target(state, None, batch, jax.random.PRNGKey(3)))
    a = np.clip(np.asarray(td3.actor_apply(state.target_actor, batch.next_obs)), -1, 1)
    q1 = np.asarray(td3.critic_net.apply(state.target_critic["q1"], batch.next_obs, a))
    q2 = np.asarray(td3.critic_net.apply(state.target_critic["q2"], batch.next_obs, a))
    assert np.any(q1 != q2)
    want = np.asarray(batch.reward) + 0.99 * (1 - np.asarray(batch.terminated)) * np.minimum(q1, q2)
    np.testing.assert_allclose(target, want, rtol=1e-6, atol=1e-6)


def test_target_smoothing_noise_is_clipped():
    """Small noise moves mu' by less than noise_clip; a huge one puts every action at mu' +- noise_clip."""
    batch = _batch()
    for stddev, exact in ((0.05, False), (1e3, True)):
        td3 = _student(policy_noise=stddev, noise_clip=0.25)
        actor = td3.init(jax.random.PRNGKey(1)).target_actor
        mu = np.asarray(td3.actor_apply(actor, batch.next_obs))
        a = np.asarray(td3.smoothed_action(actor, batch.next_obs, jax.random.PRNGKey(3)))
        assert np.all(np.abs(a) <= 1) and np.all(np.abs(a - mu) <= 0.25 + 1e-6)
        if exact:
            assert np.all(np.isclose(a, np.clip(mu + 0.25, -1, 1)) | np.isclose(a, np.clip(mu - 0.25, -1, 1)))
            assert np.any(a > mu) and np.any(a < mu)
        else:
            assert np.all(np.abs(a - mu) < 0.25) and np.any(a != mu)


def test_actor_and_targets_move_only_every_policy_delay_updates():
    td3 = _student(policy_delay=2)
    state = td3.init(jax.random.PRNGKey(1))
    batch = _batch()
    changed = lambda a, b: any(np.any(np.asarray(x) != np.asarray(y)) for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b)))
    history = []
    for _ in range(4):
        new, metrics = td3.update(state, None, batch)
        history.append((changed(new.actor, state.actor), changed(new.critic, state.critic),
                        changed(new.target_actor, state.target_actor), changed(new.target_critic, state.target_critic)))
        assert np.isfinite(float(metrics["critic_loss"])) and np.isfinite(float(metrics["actor_loss"]))
        state = new
    # updates 0 and 2 move the actor and both targets; 1 and 3 only the critics
    assert history == [(True, True, True, True), (False, True, False, False)] * 2
    assert int(state.step) == 4


def test_critic_loss_is_the_sum_of_both_critics_mse():
    td3 = _student()
    state = td3.init(jax.random.PRNGKey(1))
    batch = _batch()
    target = jnp.arange(5.0)
    loss, aux = td3.critic_loss(state.critic, None, batch, target)
    q1 = np.asarray(td3.critic_net.apply(state.critic["q1"], batch.obs, batch.action))
    q2 = np.asarray(td3.critic_net.apply(state.critic["q2"], batch.obs, batch.action))
    want = np.mean((q1 - np.arange(5.0)) ** 2) + np.mean((q2 - np.arange(5.0)) ** 2)
    np.testing.assert_allclose(float(loss), want, rtol=1e-5)
    np.testing.assert_allclose(float(aux["td_loss"]), want, rtol=1e-5)


@pytest.mark.slow
def test_td3_trains_as_the_student_of_the_noise_explorer_deterministically():
    """The same key twice gives the same numbers, the case's stored ones (tests/golden.py). (Meta's
    explorer: test_meta_on_td3_compiles_once_stays_finite_and_gives_its_stored_numbers.)"""
    case = "pendulum-ddpg-normal-td3"
    trainer = make_train(golden.case_config(case))
    assert isinstance(trainer.student, TD3)
    init, chunk = jax.jit(vmap_seeds(trainer.init)), jax.jit(vmap_seeds(trainer.train_chunk))
    runs = []
    for _ in range(2):
        state, metrics = golden.run_chunks(trainer, init, chunk)
        assert all(np.all(np.asarray(m["cycle"]["finite"])) for m in metrics)
        runs.append(golden.numbers(state, metrics))
    assert runs[0] == runs[1]
    golden.assert_stored(case, runs[0])
    assert np.all(np.asarray(state.student.step) > 0)


def test_modern_td3_preset_has_the_authors_settings():
    cfg = make_config("hopper", "ddpg", "modern", student="td3")
    assert cfg.student == "td3" and cfg.run.warmup_steps == 25_000
    assert cfg.ddpg.hidden == (256, 256) and cfg.ddpg.actor_lr == cfg.ddpg.critic_lr == 3e-4
    assert cfg.ddpg.batch_size == 256 and cfg.ddpg.tau == 0.005 and cfg.run.train_steps == cfg.run.rollout_steps == 1
    assert cfg.noise.kind == "normal" and cfg.noise.stddev == 0.1
    assert (cfg.td3.policy_noise, cfg.td3.noise_clip, cfg.td3.policy_delay) == (0.2, 0.5, 2)
    with pytest.raises(ValueError, match="unknown student"):
        make_config("hopper", "ddpg", "modern", student="redq")


@pytest.mark.slow
def test_meta_on_td3_compiles_once_stays_finite_and_gives_its_stored_numbers():
    """TD3 trains as the student of the Meta explorer, deterministically (the same key twice), to the case's
    stored numbers (tests/golden.py). (Chunked equals the single scan whatever the student and explorer:
    ``Trainer.train`` is the scan of ``train_chunk``; tests/test_train.py checks it for DDPG and for Meta.)"""
    case = "pendulum-meta-independent-td3"
    trainer = make_train(golden.case_config(case))
    assert isinstance(trainer.student, TD3)
    keys = seed_keys(*golden.KEYS)
    init = jax.jit(vmap_seeds(trainer.init))
    chunk = jax.jit(vmap_seeds(chex.assert_max_traces(n=1)(trainer.train_chunk)))
    state, metrics = golden.run_chunks(trainer, init, chunk)
    assert all(np.all(np.asarray(m["cycle"]["finite"])) for m in metrics)
    golden.assert_stored(case, golden.numbers(state, metrics))
    again = chunk(init(keys))[1]  # the same program again: no new trace, the same numbers
    np.testing.assert_array_equal(np.asarray(again["eval_return"]), np.asarray(metrics[0]["eval_return"]))
    chex.clear_trace_counter()
    assert np.all(np.asarray(state.student.step) > 0)
    assert np.all(np.isfinite(np.asarray(state.explorer.r_hat)))


@pytest.mark.slow
def test_meta_on_td3_resumed_gives_the_numbers_of_one_run(tmp_path):
    """From a checkpoint (the TD3 state's own key and update count included) to the same numbers bit for
    bit: a 600-step run extended to 900 steps equals a run started at 900. The command line stores the
    student, exports TD3's policy and refuses a student it does not have."""
    from experiments import run
    from metapg_jax import load_policy

    # A fixed replay capacity: the three calls run one program (the pytest run's compile cache loads it).
    tiny = [*tiny_argv("meta", **{"run.buffer_size": 900}), "--student=td3"]
    one, two = str(tmp_path / "one"), str(tmp_path / "two")
    assert run.main([*tiny, "--steps=900", "--out", one]) == 0
    assert run.main([*tiny, "--steps=600", "--out", two]) == 0
    assert run.main(["--quiet", "--no-plot", "--resume", two, "--steps=900"]) == 0
    rows = lambda out: [{k: r[k] for k in ("seed", "chunk", "env_steps", "eval_return", "critic_loss", "actor_loss")}
                        for r in map(json.loads, open(os.path.join(out, "metrics.jsonl")))]
    assert rows(one) == rows(two) and len(rows(one)) == 6
    a, b = np.load(os.path.join(one, "policy.npz")), np.load(os.path.join(two, "policy.npz"))
    assert sorted(a.files) == sorted(b.files)
    for name in a.files:
        np.testing.assert_array_equal(a[name], b[name])
    stored = json.load(open(os.path.join(one, "config.json")))
    assert stored["config"]["student"] == "td3" and stored["run_args"]["student"] == "td3"
    act = load_policy(os.path.join(one, "policy.npz"), seed=1)
    assert act(np.zeros(3, np.float32)).shape == (1,)
    assert run.main(["--env=pendulum", "--student=redq", "--out", str(tmp_path / "x")]) == 2
