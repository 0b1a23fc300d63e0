"""DDPG (metapg_jax/strategies/ddpg.py): losses against hand-computed numbers, targets, architecture."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from metapg_jax.config import DDPGConfig
from metapg_jax.strategies.ddpg import DDPG
from metapg_jax.types import Transition

CFG = DDPGConfig(hidden=(16, 8), layer_norm=False, critic_action_layer=1, critic_l2=0.1, gamma=0.9,
                 tau=0.5, normalize_obs=False, final_init=0.5)


def _np_actor(p):
    p = jax.tree.map(np.asarray, p)["params"]

    def f(x):
        h = np.maximum(x @ p["dense_0"]["kernel"] + p["dense_0"]["bias"], 0)
        h = np.maximum(h @ p["dense_1"]["kernel"] + p["dense_1"]["bias"], 0)
        return np.tanh(h @ p["out"]["kernel"] + p["out"]["bias"])

    return f


def _np_critic(p):
    p = jax.tree.map(np.asarray, p)["params"]

    def f(x, a):
        h = np.maximum(x @ p["dense_0"]["kernel"] + p["dense_0"]["bias"], 0)
        h = np.concatenate([h, a], -1)  # the action enters at the second layer
        h = np.maximum(h @ p["dense_1"]["kernel"] + p["dense_1"]["bias"], 0)
        return (h @ p["out"]["kernel"] + p["out"]["bias"])[..., 0]

    return f


def _batch(terminated, truncated):
    rng = np.random.default_rng(0)
    n = len(terminated)
    return Transition(obs=jnp.asarray(rng.normal(size=(n, 3)), jnp.float32),
                      action=jnp.asarray(rng.uniform(-1, 1, size=(n, 2)), jnp.float32),
                      reward=jnp.asarray(rng.normal(size=(n,)), jnp.float32),
                      next_obs=jnp.asarray(rng.normal(size=(n, 3)), jnp.float32),
                      terminated=jnp.asarray(terminated, jnp.float32),
                      truncated=jnp.asarray(truncated, jnp.float32))


@pytest.fixture(scope="module")
def setup():
    ddpg = DDPG(CFG, obs_size=3, action_size=2)
    student = ddpg.init(jax.random.PRNGKey(0))
    # Make targets differ from the online networks so the test sees which is used.
    student = student.replace(target_actor=ddpg.init(jax.random.PRNGKey(1)).actor,
                              target_critic=ddpg.init(jax.random.PRNGKey(2)).critic)
    return ddpg, student


@pytest.fixture(autouse=True)
def _numpy_precision_matmuls():
    """The hand computations are float32 NumPy; a GPU's default matmul precision (TF32 class) put the
    losses 5.4e-5 and 3.4e-4 relative away from them (measured on an H200; docs/gpu.md). A no-op on CPU."""
    with jax.default_matmul_precision("highest"):
        yield


def test_critic_loss_matches_hand_computation(setup):
    ddpg, student = setup
    batch = _batch([0.0, 1.0, 0.0], [0.0, 0.0, 1.0])
    b = jax.tree.map(np.asarray, batch)
    q_next = _np_critic(student.target_critic)(b.next_obs, _np_actor(student.target_actor)(b.next_obs))
    y = b.reward + 0.9 * (1 - b.terminated) * q_next
    q = _np_critic(student.critic)(b.obs, b.action)
    p = jax.tree.map(np.asarray, student.critic)["params"]
    l2 = sum((p[k]["kernel"] ** 2).sum() for k in ("dense_0", "dense_1"))  # not the output layer
    expected = np.mean((q - y) ** 2) + 0.5 * 0.1 * l2
    loss, aux = ddpg.critic_loss(student.critic, student, None, batch)
    np.testing.assert_allclose(loss, expected, rtol=1e-5)
    np.testing.assert_allclose(aux["q_mean"], q.mean(), rtol=1e-5)


def test_terminated_does_not_bootstrap_truncated_does(setup):
    ddpg, student = setup
    zero_l2 = DDPG(CFG.__class__(**{**CFG.__dict__, "critic_l2": 0.0}), 3, 2)
    base = _batch([0.0], [0.0])
    q = float(zero_l2.critic_net.apply(student.critic, base.obs, base.action)[0])
    b = jax.tree.map(np.asarray, base)
    q_next = float(_np_critic(student.target_critic)(b.next_obs, _np_actor(student.target_actor)(b.next_obs))[0])
    r = float(b.reward[0])
    for term, trunc, y in [(1.0, 0.0, r), (0.0, 1.0, r + 0.9 * q_next), (0.0, 0.0, r + 0.9 * q_next)]:
        batch = base.replace(terminated=jnp.array([term]), truncated=jnp.array([trunc]))
        loss, _ = zero_l2.critic_loss(student.critic, student, None, batch)
        np.testing.assert_allclose(loss, (q - y) ** 2, rtol=1e-5)


def test_actor_loss_and_update(setup):
    ddpg, student = setup
    batch = _batch([0.0, 0.0], [0.0, 0.0])
    b = jax.tree.map(np.asarray, batch)
    expected = -np.mean(_np_critic(student.critic)(b.obs, _np_actor(student.actor)(b.obs)))
    np.testing.assert_allclose(ddpg.actor_loss(student.actor, student, None, batch), expected, rtol=1e-5)
    new, metrics = jax.jit(ddpg.update)(student, None, batch)
    # Soft target update with tau = 0.5 toward the *updated* online parameters.
    t = jax.tree.map(lambda old, on: 0.5 * old + 0.5 * on, student.target_critic, new.critic)
    jax.tree.map(lambda a, b: np.testing.assert_allclose(a, b, rtol=1e-6), t, new.target_critic)
    assert float(metrics["critic_loss"]) > 0
    # Adam's first step moves every parameter that has a gradient.
    moved = jax.tree.map(lambda a, b: bool(np.any(a != b)), student.actor, new.actor)
    assert all(jax.tree.leaves(moved))


def test_different_seeds_give_different_parameters():
    ddpg = DDPG(DDPGConfig(), 3, 1)
    a = jax.vmap(ddpg.init)(jax.random.split(jax.random.PRNGKey(0), 2))
    k0 = a.actor["params"]["dense_0"]["kernel"]
    assert not np.allclose(k0[0], k0[1])


def test_baselines_architecture_and_init():
    ddpg = DDPG(DDPGConfig(), 5, 2)
    s = ddpg.init(jax.random.PRNGKey(0))
    p = s.critic["params"]
    assert p["dense_0"]["kernel"].shape == (5, 64)
    assert p["dense_1"]["kernel"].shape == (64 + 2, 64)   # action at the second layer
    assert "ln_0" in p and "ln_1" in p
    assert float(jnp.abs(s.actor["params"]["out"]["kernel"]).max()) <= 3e-3
