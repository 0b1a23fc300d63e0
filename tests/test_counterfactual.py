"""The counterfactual meta reward and the look-ahead's data (metapg_jax/counterfactual.py): what each
sampler draws from, and the cycle with ``meta.baseline='counterfactual'`` and ``meta.lookahead_data='mix'``."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from metapg_jax import replay
from metapg_jax.config import validate
from metapg_jax import counterfactual
from metapg_jax.train import make_train
from metapg_jax.types import Transition
from tests.helpers import tiny_config


def _transitions(n, reward):
    return Transition(obs=jnp.zeros((n, 3)), action=jnp.zeros((n, 1)), reward=jnp.full((n,), reward, jnp.float32),
                      next_obs=jnp.zeros((n, 3)), terminated=jnp.zeros((n,), jnp.float32),
                      truncated=jnp.zeros((n,), jnp.float32))


def _buffer(n, reward=1.0, capacity=64):
    return replay.add(replay.init(capacity, 3, 1), _transitions(n, reward)) if n else replay.init(capacity, 3, 1)


def test_the_samplers_draw_from_d0_the_mix_or_the_buffer_alone():
    """Rewards mark the source (buffer 1, D0 -1): 'd0' draws D0 only; 'mix' both, in proportion to their sizes,
    and D0 only from an empty buffer; the counterfactual's buffer sampler never D0."""
    d0, buf = _transitions(10, -1.0), _buffer(30)
    keys = jax.random.split(jax.random.PRNGKey(0), 200)
    draw = lambda sample: np.concatenate([np.asarray(sample(k).reward) for k in keys])
    assert set(draw(counterfactual.lookahead_sampler("d0", buf, d0, 16))) == {-1.0}
    mixed = draw(counterfactual.lookahead_sampler("mix", buf, d0, 16))
    assert set(mixed) == {-1.0, 1.0}
    assert np.mean(mixed == -1.0) == pytest.approx(10 / 40, abs=0.03)
    assert set(draw(counterfactual.lookahead_sampler("mix", _buffer(0), d0, 16))) == {-1.0}
    assert set(draw(lambda k: replay.sample(buf, k, 16))) == {1.0}


def test_the_counterfactual_cycle_rewards_r_pi_prime_minus_r_pi_second_once_the_buffer_can_train_it():
    """Two eval envs, the mixed look-ahead: the first cycle's buffer is empty, so no pi'' and a meta reward of 0;
    after it, the meta reward is R_hat(pi') - R_hat(pi''), not 0, and pi'''s rollout is stored and counted like D1;
    a bad ``meta.lookahead_data`` is refused in one line."""
    overrides = {"meta.baseline": "counterfactual", "meta.lookahead_data": "mix", "meta.eval_envs": 2}
    per_cycle = 50 + 2 * 100 * 2
    trainer = make_train(tiny_config("meta", steps=4 * per_cycle, eval_every=2 * per_cycle, **overrides))
    assert trainer.config.steps_per_cycle == per_cycle
    cycle = jax.jit(trainer.cycle)
    state = trainer.init(jax.random.PRNGKey(0))
    state, m0 = cycle(state)
    assert float(m0["meta_reward"]) == 0.0 and np.isnan(float(m0["r_hat_pi"]))
    rewards = []
    for _ in range(2):
        state, m = cycle(state)
        assert np.isfinite(float(m["r_hat_pi"]))
        np.testing.assert_allclose(m["meta_reward"], m["r_hat_lookahead"] - m["r_hat_pi"], rtol=1e-6)
        assert np.isfinite(float(m["meta_reward_sd_paired"]))
        rewards.append(float(m["meta_reward"]))
    assert any(r != 0.0 for r in rewards)
    assert int(state.env_steps) == 3 * per_cycle == int(state.buffer.size)
    with pytest.raises(ValueError, match="meta.lookahead_data must be one of d0, mix, got 'both'"):
        validate(tiny_config("meta", steps=300, **{"meta.lookahead_data": "both"}))
