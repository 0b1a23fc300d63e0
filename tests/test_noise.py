"""The DDPG baselines' noises (metapg_jax/strategies/noise.py): Gaussian, Ornstein-Uhlenbeck, adaptive parameter
noise."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from metapg_jax.config import DDPGConfig
from metapg_jax.strategies import noise as noise_lib
from metapg_jax.strategies.ddpg import DDPG
from metapg_jax.strategies.noise import NoiseConfig


def test_noise_kinds():
    ddpg = DDPG(DDPGConfig(), 3, 2)
    actor = ddpg.init(jax.random.PRNGKey(0)).actor
    obs = jnp.ones(3)
    key = jax.random.PRNGKey(1)
    mu = ddpg.actor_apply(actor, obs)
    # normal: mean zero around mu; clipped.
    cfg = NoiseConfig(kind="normal", stddev=0.3)
    st = noise_lib.init(cfg, actor, 2)
    acts = jax.vmap(lambda k: noise_lib.act(cfg, st, ddpg.actor_apply, actor, obs, k)[0])(jax.random.split(key, 4000))
    np.testing.assert_allclose(acts.mean(0), mu, atol=0.03)
    np.testing.assert_allclose(acts.std(0), 0.3, atol=0.03)
    # OU: the state moves and resets to zero at an episode start.
    cfg = NoiseConfig(kind="ou", stddev=0.3)
    st = noise_lib.init(cfg, actor, 2)
    _, st = noise_lib.act(cfg, st, ddpg.actor_apply, actor, obs, key)
    assert float(jnp.abs(st.ou).sum()) > 0
    assert float(jnp.abs(noise_lib.episode_start(cfg, st, actor, key).ou).sum()) == 0
    # Parameter noise perturbs everything but LayerNorm; adaptation shrinks a too-large stddev.
    cfg = NoiseConfig(kind="adaptive-param", stddev=0.2)
    st = noise_lib.episode_start(cfg, noise_lib.init(cfg, actor, 2), actor, key)
    p, q = actor["params"], st.perturbed["params"]
    assert not np.allclose(p["dense_0"]["kernel"], q["dense_0"]["kernel"])
    np.testing.assert_array_equal(p["ln_0"]["scale"], q["ln_0"]["scale"])
    big = st.replace(stddev=jnp.asarray(5.0))
    obs_b = jax.random.normal(key, (64, 3))
    assert float(noise_lib.adapt(cfg, big, ddpg.actor_apply, actor, obs_b, key).stddev) == pytest.approx(5.0 / 1.01)
    small = st.replace(stddev=jnp.asarray(1e-4))
    assert float(noise_lib.adapt(cfg, small, ddpg.actor_apply, actor, obs_b, key).stddev) == pytest.approx(1.01e-4)
