"""What every built-in student shares: the actor and critic networks and optimisers of the ``ddpg`` config group
(the core's actor-critic settings), observation normalisation and acting. The quickest start for a new
student (``metapg_jax.strategies.ddpg`` and ``td3`` build on it); ``policy.npz`` export reproduces its actor.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import jax
import jax.numpy as jnp
import optax

from metapg_jax import normalizer as norm_lib
from metapg_jax import strategy
from metapg_jax.config import DDPGConfig
from metapg_jax.networks import Actor, Critic, is_hidden_kernel_path
from metapg_jax.types import Params, Transition


@dataclasses.dataclass(frozen=True)
class ActorCritic(strategy.Student):
    """What every built-in student shares (DDPG, TD3, SAC): the actor and critic networks and
    optimisers of the ``ddpg`` config group, observation normalisation and acting. Pure and jittable; a
    subclass writes ``init`` and ``update``, with ``.actor`` and ``.critic`` in its state."""

    cfg: DDPGConfig
    obs_size: int
    action_size: int

    @property
    def actor_net(self) -> Actor:
        return Actor(self.action_size, tuple(self.cfg.hidden), self.cfg.layer_norm, self.cfg.final_init)

    @property
    def critic_net(self) -> Critic:
        return Critic(tuple(self.cfg.hidden), self.cfg.layer_norm, self.cfg.critic_action_layer, self.cfg.final_init)

    @property
    def actor_opt(self) -> optax.GradientTransformation:
        return optax.adam(self.cfg.actor_lr)

    @property
    def critic_opt(self) -> optax.GradientTransformation:
        return optax.adam(self.cfg.critic_lr)

    # -- acting ---------------------------------------------------------------
    def normalize(self, normalizer: norm_lib.NormalizerState, obs: jax.Array) -> jax.Array:
        return norm_lib.normalize(normalizer if self.cfg.normalize_obs else None, obs, self.cfg.obs_clip)

    def actor_apply(self, actor: Params, obs_normalized: jax.Array) -> jax.Array:
        return self.actor_net.apply(actor, obs_normalized)

    def deterministic_policy(self, actor: Params, normalizer) -> Callable[[jax.Array], jax.Array]:
        """mu(s) on raw observations: what evaluation and the look-ahead rollout D1 use."""
        return lambda obs: self.actor_apply(actor, self.normalize(normalizer, obs))

    def guarded_params(self, state) -> tuple[Params, Params]:
        """The NaN guard checks the actor and the critic."""
        return state.actor, state.critic

    def init_actor_and_twin_critics(self, key: jax.Array) -> tuple[Params, Params, jax.Array]:
        """TD3's and SAC's initial parameters: (the actor, the twin critics ``{"q1", "q2"}``, the key left for the
        student's state), from one key split four ways (actor, Q1, Q2, state)."""
        k_actor, k_q1, k_q2, k_state = jax.random.split(key, 4)
        obs = jnp.zeros((self.obs_size,), jnp.float32)
        act = jnp.zeros((self.action_size,), jnp.float32)
        critic = {"q1": self.critic_net.init(k_q1, obs, act), "q2": self.critic_net.init(k_q2, obs, act)}
        return self.actor_net.init(k_actor, obs), critic, k_state

    # -- learning -------------------------------------------------------------
    def twin_critic_loss(self, critic: Params, normalizer, batch: Transition, target: jax.Array):
        """Twin critics ``{"q1", "q2"}`` (TD3, SAC): mean (Q1(s, a) - y)^2 + mean (Q2(s, a) - y)^2 for the
        target ``y``, plus ``critic_l2`` on both critics' hidden kernels (sum w^2 / 2). Aux: Q1's mean, the TD loss."""
        obs = self.normalize(normalizer, batch.obs)
        q1 = self.critic_net.apply(critic["q1"], obs, batch.action)
        q2 = self.critic_net.apply(critic["q2"], obs, batch.action)
        td_loss = jnp.mean(jnp.square(q1 - target)) + jnp.mean(jnp.square(q2 - target))
        l2 = sum(jnp.sum(jnp.square(w)) for path, w in jax.tree_util.tree_leaves_with_path(critic)
                 if is_hidden_kernel_path(path))
        return td_loss + 0.5 * self.cfg.critic_l2 * l2, {"q_mean": jnp.mean(q1), "td_loss": td_loss}


def actor_architecture(config) -> dict:
    """The acting policy of an ``ActorCritic`` student as ``policy.npz`` describes it for its NumPy loader
    (``metapg_jax.host.policy``): an MLP on clipped normalised observations, ReLU hidden layers (LayerNorm
    after each Dense if set), tanh output; the parameters are ``dense_<i>``, ``ln_<i>`` and ``out``."""
    c = config.ddpg
    return {"kind": "mlp", "hidden": list(c.hidden), "layer_norm": bool(c.layer_norm), "layer_norm_epsilon": 1e-6,
            "normalize_obs": bool(c.normalize_obs), "obs_clip": float(c.obs_clip), "activation": "relu",
            "output": "tanh"}
