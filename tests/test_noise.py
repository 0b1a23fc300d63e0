"""Action noise: the noise explorer's (metapg_jax/strategies/noise.py) Gaussian, Ornstein-Uhlenbeck and adaptive
parameter noise, the kinds of metapg_jax/action_noise.py, colored noise (strategies/pink.py) and per-episode scales
(strategies/mixed.py)."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from metapg_jax import action_noise
from metapg_jax.config import DDPGConfig, make_config
from metapg_jax.strategies import noise as noise_lib
from metapg_jax.strategies.ddpg import DDPG
from metapg_jax.action_noise import colored_sequence
from metapg_jax.train import make_train, seed_keys, vmap_seeds
from tests.helpers import tiny_config


def _config(kind, **fields):
    return make_config("pendulum", "ddpg", overrides={"noise.kind": kind, **fields})


def test_noise_kinds():
    ddpg = DDPG(DDPGConfig(), 3, 2)
    actor = ddpg.init(jax.random.PRNGKey(0)).actor
    obs = jnp.ones(3)
    key = jax.random.PRNGKey(1)
    mu = ddpg.actor_apply(actor, obs)
    # normal: mean zero around mu; clipped.
    cfg = _config("normal", **{"noise.stddev": 0.3})
    st = noise_lib.init(cfg, actor, 2)
    acts = jax.vmap(lambda k: noise_lib.act(cfg, st, ddpg.actor_apply, actor, obs, k)[0])(jax.random.split(key, 4000))
    np.testing.assert_allclose(acts.mean(0), mu, atol=0.03)
    np.testing.assert_allclose(acts.std(0), 0.3, atol=0.03)
    # OU: the state moves and resets to zero at an episode start.
    cfg = _config("ou", **{"noise.stddev": 0.3})
    st = noise_lib.init(cfg, actor, 2)
    _, st = noise_lib.act(cfg, st, ddpg.actor_apply, actor, obs, key)
    assert float(jnp.abs(st.process).sum()) > 0
    assert float(jnp.abs(noise_lib.episode_start(cfg, st, actor, key).process).sum()) == 0
    # Parameter noise perturbs everything but LayerNorm; adaptation shrinks a too-large stddev.
    cfg = _config("adaptive-param", **{"noise.stddev": 0.2})
    st = noise_lib.episode_start(cfg, noise_lib.init(cfg, actor, 2), actor, key)
    p, q = actor["params"], st.perturbed["params"]
    assert not np.allclose(p["dense_0"]["kernel"], q["dense_0"]["kernel"])
    np.testing.assert_array_equal(p["ln_0"]["scale"], q["ln_0"]["scale"])
    big = st.replace(stddev=jnp.asarray(5.0))
    obs_b = jax.random.normal(key, (64, 3))
    assert float(noise_lib.adapt(cfg, big, ddpg.actor_apply, actor, obs_b, key).stddev) == pytest.approx(5.0 / 1.01)
    small = st.replace(stddev=jnp.asarray(1e-4))
    assert float(noise_lib.adapt(cfg, small, ddpg.actor_apply, actor, obs_b, key).stddev) == pytest.approx(1.01e-4)


@pytest.mark.parametrize("beta", [0.0, 1.0, 2.0])
def test_colored_noise_has_the_power_law_spectrum_and_unit_variance(beta):
    """Over many draws the averaged periodogram's fitted log-log slope is -beta (within 0.15), and every step has
    variance 1 (the action noise is stddev * z: variance stddev^2)."""
    length, draws = 1000, 2000
    z = jax.jit(jax.vmap(lambda k: colored_sequence(k, beta, length, 1)[:, 0]))(
        jax.random.split(jax.random.PRNGKey(3), draws))
    z = np.asarray(z, np.float64)
    power = np.mean(np.abs(np.fft.rfft(z, axis=1)) ** 2, axis=0)
    f = np.fft.rfftfreq(length)[1:-1]                     # without the DC and Nyquist terms
    slope = np.polyfit(np.log(f), np.log(power[1:-1]), 1)[0]
    assert abs(slope + beta) < 0.15, slope
    per_step = z.var(axis=0)
    assert abs(per_step.mean() - 1.0) < 0.05 and np.all(np.abs(per_step - 1.0) < 0.2), (per_step.mean(), per_step)
    cfg = _config("pink", **{"noise.stddev": 0.3, "pink.beta": beta})
    process = action_noise.episode_start(cfg, action_noise.init(cfg, 2), jax.random.PRNGKey(0))
    _, scale, _ = action_noise.sample(cfg, process, jax.random.PRNGKey(1))
    assert scale == 0.3


def test_a_colored_sequence_is_drawn_at_every_episode_start_and_read_step_by_step():
    cfg = _config("pink", **{"env.episode_length": 70})
    process = action_noise.init(cfg, 2)
    assert process.sequence.shape == (70, 2)
    first = process = action_noise.episode_start(cfg, process, jax.random.PRNGKey(1))
    for t in range(3):
        z, _, process = action_noise.sample(cfg, process, jax.random.PRNGKey(10 + t))
        np.testing.assert_array_equal(z, first.sequence[t])
    np.testing.assert_array_equal(process.sequence, first.sequence)   # not redrawn between starts
    again = action_noise.episode_start(cfg, process, jax.random.PRNGKey(2))
    assert int(again.step) == 0 and not np.allclose(again.sequence, first.sequence)


@functools.lru_cache(maxsize=None)
def _one_step_cycles(kind):
    """A chunk of 300 one-step cycles (so each cycle's metrics show the noise at that step), 70-step episodes."""
    cfg = tiny_config("ddpg", steps=300, **{"noise.kind": kind, "run.rollout_steps": 1, "run.train_steps": 1,
                                            "env.episode_length": 70})
    trainer = make_train(cfg)
    state = jax.jit(vmap_seeds(trainer.init))(seed_keys(0, 2))
    return cfg, jax.jit(vmap_seeds(trainer.train_chunk))(state)


def test_colored_noise_restarts_with_the_episodes_of_a_run():
    _, (state, _) = _one_step_cycles("pink")
    # 300 steps of 70-step episodes: the fifth episode is at its step 20, and so is the sequence.
    np.testing.assert_array_equal(np.asarray(state.explorer.process.step), [20, 20])
    np.testing.assert_array_equal(np.asarray(state.env_state.info["steps"]), [20, 20])


def test_per_episode_scales_lie_in_the_range_and_change_only_when_an_episode_starts():
    cfg, (_, metrics) = _one_step_cycles("mixed")
    scale = np.asarray(metrics["cycle"]["noise_scale"])          # (seeds, steps)
    assert scale.shape == (2, 300)
    assert np.all(scale >= cfg.mixed.min_stddev) and np.all(scale <= cfg.mixed.max_stddev)
    episode = np.arange(300) // 70
    for s in scale:
        for e in range(5):
            assert len(set(s[episode == e].tolist())) == 1, e
        assert len(set(s.tolist())) == 5
    assert not np.array_equal(scale[0], scale[1])


def test_adaptive_parameter_noise_is_a_value_of_noise_kind_but_no_registered_kind():
    """The ddpg explorer has it built in (metapg_jax/action_noise.py's docstring says why)."""
    assert action_noise.PARAMETER_NOISE == noise_lib.PARAMETER_NOISE == "adaptive-param"
    assert "adaptive-param" in noise_lib.names() and "adaptive-param" not in action_noise.kinds()


@pytest.mark.parametrize("overrides,message", [
    ({"noise.kind": "pink", "pink.beta": -1.0}, "pink.beta must be a finite number >= 0"),
    ({"noise.kind": "mixed", "mixed.min_stddev": 0.5, "mixed.max_stddev": 0.1}, "0 <= min <= max"),
    ({"noise.kind": "brown"}, "unknown noise 'brown'; valid noises: adaptive-param, mixed, none, normal, ou, pink"),
])
def test_bad_kind_settings_are_refused(overrides, message):
    from metapg_jax.config import validate

    with pytest.raises(ValueError, match=message):
        validate(make_config("pendulum", "ddpg", overrides=overrides))
