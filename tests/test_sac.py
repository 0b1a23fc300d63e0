"""SAC (metapg_jax/strategies/sac.py): its three losses and the update's order against a hand computation, the
squashed Gaussian's log-probability against a numerical change of variables, the temperature's direction,
SAC as the student of the Meta explorer (one compile, finite numbers) and its policy.npz export."""

import json
import math
import os

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from metapg_jax import normalizer as norm_lib
from metapg_jax import strategy
from metapg_jax.config import DDPGConfig, make_config, validate
from metapg_jax.host.policy import describe, export_policies, load_policy
from metapg_jax.strategies.sac import SAC, SACConfig, squashed_gaussian_log_prob
from metapg_jax.train import make_train, seed_keys, vmap_seeds
from metapg_jax.types import Transition
from tests import golden
from tests.helpers import rewind_resume_and_compare, tiny_argv

GAMMA, TAU, L2 = 0.99, 0.01, 0.01


def _student(**sac):
    # A larger last-layer init than the presets' so that means and log-stds differ between rows and actions.
    return SAC(DDPGConfig(hidden=(8, 8), layer_norm=False, critic_action_layer=0, critic_l2=L2, final_init=0.5,
                          normalize_obs=False, tau=TAU, gamma=GAMMA), obs_size=3, action_size=2,
               sac=SACConfig(**sac))


def _batch(n=4, seed=0):
    k = jax.random.split(jax.random.PRNGKey(seed), 4)
    return Transition(obs=jax.random.normal(k[0], (n, 3)), action=jax.random.uniform(k[1], (n, 2), minval=-1, maxval=1),
                      reward=jax.random.normal(k[2], (n,)), next_obs=jax.random.normal(k[3], (n, 3)),
                      terminated=jnp.array([0, 1, 0, 0], jnp.float32)[:n], truncated=jnp.zeros((n,)))


def _np(x):
    return np.asarray(x, np.float64)


def _policy_by_hand(sac, actor, obs, key):
    """NumPy: the actor MLP's outputs -> (mean, log_std) -> a = tanh(mean + std z) and log pi(a|s), with the
    textbook log(1 - tanh(u)^2) (exact enough at these moderate u in float64)."""
    out = _np(sac.actor_net.apply(actor, obs))
    mean, raw = out[:, :2], out[:, 2:]
    log_std = -5.0 + 0.5 * 7.0 * (np.tanh(raw) + 1.0)
    z = _np(jax.random.normal(key, mean.shape))
    u = mean + np.exp(log_std) * z
    gauss = -0.5 * z ** 2 - log_std - 0.5 * np.log(2 * np.pi)
    return np.tanh(u), np.sum(gauss - np.log(1.0 - np.tanh(u) ** 2), axis=-1)


def _q(sac, critic, obs, action):
    return (_np(sac.critic_net.apply(critic["q1"], obs, jnp.asarray(action, jnp.float32))),
            _np(sac.critic_net.apply(critic["q2"], obs, jnp.asarray(action, jnp.float32))))


def test_the_three_losses_and_the_update_order_match_a_hand_computation():
    """Critic step on the soft target (a' from the current actor, the start's alpha), then the actor on the
    stepped critics, then the temperature with the actor's sample, then the critics' targets."""
    sac = _student(init_alpha=0.5, alpha_lr=1e-2)
    state = sac.init(jax.random.PRNGKey(4))
    # Targets unlike the critics, so that a mix-up shows (keys where neither critic is always the smaller).
    state = state.replace(target_critic=sac.init(jax.random.PRNGKey(3)).critic)
    batch = _batch()
    obs, next_obs = _np(batch.obs), _np(batch.next_obs)
    r, done = _np(batch.reward), _np(batch.terminated)
    _, k_next, k_pi = jax.random.split(state.key, 3)
    alpha, target_entropy = 0.5, -2.0

    a_next, logp_next = _policy_by_hand(sac, state.actor, next_obs, k_next)
    q1_next, q2_next = _q(sac, state.target_critic, next_obs, a_next)
    assert np.any(q1_next < q2_next) and np.any(q1_next > q2_next)
    y = r + GAMMA * (1 - done) * (np.minimum(q1_next, q2_next) - alpha * logp_next)
    np.testing.assert_allclose(_np(sac.target(state, None, batch, jnp.float32(alpha), k_next)), y, rtol=1e-5, atol=1e-5)

    q1, q2 = _q(sac, state.critic, obs, batch.action)
    kernels = [_np(state.critic[q]["params"][f"dense_{i}"]["kernel"]) for q in ("q1", "q2") for i in (0, 1)]
    td = np.mean((q1 - y) ** 2) + np.mean((q2 - y) ** 2)
    critic_loss = td + 0.5 * L2 * sum(np.sum(w ** 2) for w in kernels)

    new, metrics = sac.update(state, None, batch)
    a_pi, logp_pi = _policy_by_hand(sac, state.actor, obs, k_pi)  # the actor before its step
    q1_pi, q2_pi = _q(sac, new.critic, obs, a_pi)                  # the critics after theirs
    assert np.any(q1_pi < q2_pi) and np.any(q1_pi > q2_pi)
    actor_loss = np.mean(alpha * logp_pi - np.minimum(q1_pi, q2_pi))
    alpha_loss = np.mean(-alpha * (logp_pi + target_entropy))
    want = {"critic_loss": critic_loss, "td_loss": td, "q_mean": np.mean(q1), "actor_loss": actor_loss,
            "alpha_loss": alpha_loss, "alpha": alpha, "entropy": -np.mean(logp_pi)}
    assert set(metrics) == set(want)
    for name, value in want.items():
        np.testing.assert_allclose(float(metrics[name]), value, rtol=1e-5, atol=1e-5, err_msg=name)
    # The temperature's first Adam step is -alpha_lr * sign(dL/dlog_alpha), dL/dlog_alpha = alpha_loss here.
    np.testing.assert_allclose(float(new.log_alpha), math.log(alpha) - 1e-2 * np.sign(alpha_loss), rtol=1e-5)
    # Soft targets of the stepped critics; the actor and the key moved.
    for t_new, t_old, c in zip(*(jax.tree.leaves(x) for x in (new.target_critic, state.target_critic, new.critic))):
        np.testing.assert_allclose(_np(t_new), (1 - TAU) * _np(t_old) + TAU * _np(c), rtol=1e-5, atol=1e-7)
    assert any(np.any(_np(a) != _np(b)) for a, b in zip(jax.tree.leaves(new.actor), jax.tree.leaves(state.actor)))
    assert np.any(np.asarray(new.key) != np.asarray(state.key))
    # A fixed temperature: the same losses, log_alpha stays.
    fixed, fixed_metrics = _student(init_alpha=0.5, alpha_lr=1e-2, learn_alpha=False).update(state, None, batch)
    assert float(fixed.log_alpha) == float(state.log_alpha)
    np.testing.assert_allclose(float(fixed_metrics["actor_loss"]), actor_loss, rtol=1e-5, atol=1e-5)


def test_log_prob_is_the_change_of_variables_through_tanh_also_where_tanh_saturates():
    """log pi(tanh(u)) = log N(u; mean, std) - log |det d tanh(u) / du| (Jacobian by jax.jacfwd, float64)."""
    u = np.array([0.3, -1.2, 4.0, 8.0, -8.0, 12.0], np.float64)
    mean = np.array([0.1, -1.0, 3.0, 7.5, -7.0, 11.0], np.float64)
    log_std = np.array([-0.5, 0.2, -1.0, 0.0, 0.5, -2.0], np.float64)
    with jax.enable_x64(True):
        jac = jax.jacfwd(jnp.tanh)(jnp.asarray(u))
        _, log_det = jnp.linalg.slogdet(jac)
        gauss = jnp.sum(jax.scipy.stats.norm.logpdf(jnp.asarray(u), jnp.asarray(mean), jnp.exp(jnp.asarray(log_std))))
        want = float(gauss - log_det)
        assert np.isfinite(want)
    got = squashed_gaussian_log_prob(jnp.asarray(u, jnp.float32), jnp.asarray(mean, jnp.float32),
                                     jnp.asarray(log_std, jnp.float32))
    np.testing.assert_allclose(float(got), want, rtol=1e-5)
    # One dimension at |u| = 8, where the float32 log(1 - tanh(u)^2 + 1e-6) of SB3 / CleanRL is ~1 nat off.
    for x in (8.0, -8.0):
        one = lambda v: squashed_gaussian_log_prob(jnp.asarray([v], jnp.float32), jnp.zeros(1), jnp.zeros(1))
        with jax.enable_x64(True):
            exact = -0.5 * x * x - 0.5 * math.log(2 * math.pi) - float(jnp.log(jax.jacfwd(jnp.tanh)(jnp.float64(x))))
        y = np.tanh(np.float32(x))
        naive = -0.5 * x * x - 0.5 * math.log(2 * math.pi) - float(np.log(np.float32(1) - y * y + np.float32(1e-6)))
        np.testing.assert_allclose(float(one(x)), exact, rtol=1e-6)
        assert abs(naive - exact) > 0.5
        assert np.isfinite(float(jax.grad(one)(x)))


def test_the_temperature_falls_above_the_target_entropy_and_rises_below_it():
    sac = _student(alpha_lr=3e-2)
    state = sac.init(jax.random.PRNGKey(0))
    target = sac.target_entropy
    assert target == -2.0 and float(jnp.exp(state.log_alpha)) == pytest.approx(1.0)

    def alphas(entropy):
        log_prob = jnp.full((16,), -entropy)

        def step(carry, _):
            log_alpha, opt = carry
            log_alpha, opt, _ = sac.temperature_step(log_alpha, opt, log_prob)
            return (log_alpha, opt), jnp.exp(log_alpha)

        return np.asarray(jax.lax.scan(step, (state.log_alpha, state.alpha_opt), None, length=100)[1])

    high, low = alphas(target + 1.0), alphas(target - 1.0)
    assert np.all(np.diff(high) < 0) and high[-1] < 0.2
    assert np.all(np.diff(low) > 0) and low[-1] > 5.0
    # The sign of the loss's gradient, directly: positive (alpha falls) exactly when the entropy is above target.
    grad = jax.grad(sac.alpha_loss)
    assert float(grad(state.log_alpha, jnp.full((4,), -(target + 0.1)))) > 0
    assert float(grad(state.log_alpha, jnp.full((4,), -(target - 0.1)))) < 0


def test_sac_group_defaults_overrides_and_checks():
    spec = strategy.student("sac")
    assert spec.stochastic and spec.group is SACConfig
    cfg = make_config("pendulum", "meta", student="sac", overrides={"sac.init_alpha": "0.2", "sac.learn_alpha": "no"})
    assert cfg.sac == SACConfig(init_alpha=0.2, learn_alpha=False)
    validate(cfg)
    assert make_config("pendulum", "meta").sac == SACConfig()  # every config has the group
    for field, value in (("alpha_lr", "0"), ("alpha_lr", "inf"), ("init_alpha", "-1"), ("log_std_min", "2.0")):
        with pytest.raises(ValueError, match=f"sac.{field}") as err:
            validate(make_config("pendulum", "meta", student="sac", overrides={f"sac.{field}": value}))
        assert "\n" not in str(err.value)


@pytest.mark.slow
def test_meta_on_sac_compiles_once_and_trains_two_chunks_with_finite_numbers():
    """The teacher of Algorithm 1 on the SAC student: its look-ahead copy is a SAC state, D1 and the evaluation
    run tanh(mean). The seed-vmapped train_chunk is traced and compiled once for both chunks."""
    case = "pendulum-meta-independent-sac"
    trainer = make_train(golden.case_config(case))
    cfg = trainer.config
    assert isinstance(trainer.student, SAC) and cfg.num_chunks == 2
    init = jax.jit(vmap_seeds(trainer.init))
    chunk = jax.jit(vmap_seeds(chex.assert_max_traces(n=1)(trainer.train_chunk)))
    log_alpha0 = np.asarray(init(seed_keys(*golden.KEYS)).student.log_alpha)
    state, chunks = golden.run_chunks(trainer, init, chunk)
    for metrics in chunks:
        cycle = metrics["cycle"]
        assert np.all(np.asarray(cycle["finite"]))
        for name in ("critic_loss", "actor_loss", "alpha_loss", "alpha", "entropy", "lookahead_critic_loss"):
            assert np.all(np.isfinite(np.asarray(cycle[name]))), name
        assert np.all(np.isfinite(np.asarray(metrics["eval_return"])))
    assert chunk._cache_size() == 1
    chex.clear_trace_counter()
    golden.assert_stored(case, golden.numbers(state, chunks))
    assert np.all(np.asarray(state.env_steps) == 600)
    assert np.all(np.asarray(state.student.log_alpha) != log_alpha0)  # the temperature learned
    assert np.all(np.isfinite(np.asarray(state.student.log_alpha)))

    # Acting: deterministic tanh(mean) on raw observations, samples tanh(mean + std z), both in [-1, 1].
    sac = trainer.student
    actor, normalizer = jax.tree.map(lambda x: x[0], (state.student.actor, state.normalizer))
    obs = jax.random.normal(jax.random.PRNGKey(3), (5, sac.obs_size)) * 3.0
    act = sac.deterministic_policy(actor, normalizer)
    assert act(obs[0]).shape == (1,) and act(obs).shape == (5, 1)
    obs_n = sac.normalize(normalizer, obs[0])
    mean, log_std = sac.distribution(actor, obs_n)
    np.testing.assert_allclose(np.asarray(act(obs[0])), np.tanh(np.asarray(mean)), rtol=1e-6)
    assert np.all((np.asarray(log_std) >= -5.0) & (np.asarray(log_std) <= 2.0))
    np.testing.assert_allclose(np.asarray(sac.sample_action(actor, obs_n, jnp.zeros(1))), np.asarray(act(obs[0])),
                               rtol=1e-6)
    z = jnp.array([40.0])
    sample = sac.sample_action(actor, obs_n, z)
    assert sample.shape == (1,) and np.all(np.abs(np.asarray(sample)) <= 1.0)
    np.testing.assert_allclose(np.asarray(sample), np.tanh(np.asarray(mean + jnp.exp(log_std) * z)), rtol=1e-6)


def test_policy_export_round_trip_gives_tanh_of_the_mean(tmp_path):
    """policy.npz of a SAC actor: the description's action_size is |A| (the last layer has 2 |A| columns) and
    the NumPy loader's action is tanh(mean) as in JAX, with LayerNorm and observation normalisation."""
    cfg = make_config("pendulum", "meta", student="sac",
                      overrides={"ddpg.hidden": "8,8", "ddpg.final_init": "1.0"})  # paper preset: LayerNorm, normaliser
    assert cfg.ddpg.layer_norm and cfg.ddpg.normalize_obs
    sac = strategy.student("sac").make(cfg, 3, 1)
    keys = seed_keys(0, 2)
    actors = jax.vmap(sac.init)(keys).actor
    data = jax.random.normal(jax.random.PRNGKey(5), (2, 50, 3)) * jnp.array([1.0, 2.0, 5.0]) + 1.0
    normalizers = jax.vmap(lambda d: norm_lib.update(norm_lib.init(3), d))(data)
    path = str(tmp_path / "policy.npz")
    export_policies(path, cfg, jax.device_get(actors), jax.device_get(normalizers))
    desc = describe(path)
    assert desc["output"] == "tanh-mean" and desc["action_size"] == 1 and desc["obs_size"] == 3
    obs = np.random.default_rng(0).normal(size=(7, 3)).astype(np.float32) * 4.0
    for seed in range(2):
        actor, normalizer = jax.tree.map(lambda x: x[seed], (actors, normalizers))
        want = np.asarray(sac.deterministic_policy(actor, normalizer)(jnp.asarray(obs)))
        act = load_policy(path, seed=seed)
        assert act(obs).shape == (7, 1) and act(obs[0]).shape == (1,)
        np.testing.assert_allclose(act(obs), want, rtol=1e-5, atol=1e-6)
        assert np.std(want) > 1e-2  # the means vary: the check is not of zeros


@pytest.mark.slow
def test_a_sac_run_with_colored_noise_resumes_bit_for_bit(tmp_path):
    """SAC exploring with its own policy and pink sampling noise: the temperature, the student's key and the
    colored sequence are in the checkpoint, so a run resumed from it mid-episode (70-step episodes, 300-step
    chunks) draws the same noise and ends with the numbers of an uninterrupted one."""
    args = [*tiny_argv("own", **{"run.buffer_size": 1800, "env.episode_length": 70}), "--student=sac",
            "--noise=pink", "--steps=1800", "--checkpoint-every=1"]
    full = rewind_resume_and_compare(tmp_path, args)
    stored = json.load(open(os.path.join(full, "config.json")))["config"]
    assert stored["student"] == "sac" and stored["noise"]["kind"] == "pink"
