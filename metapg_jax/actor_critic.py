"""What every built-in student shares: the actor and critic networks and optimisers of the ``ddpg`` config group
(the core's actor-critic settings), observation normalisation and acting. The quickest start for a new
student (``metapg_jax.strategies.ddpg`` and ``td3`` build on it); ``policy.npz`` export reproduces its actor.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import jax
import optax

from metapg_jax import normalizer as norm_lib
from metapg_jax.config import DDPGConfig
from metapg_jax.networks import Actor, Critic
from metapg_jax.types import Params


@dataclasses.dataclass(frozen=True)
class ActorCritic:
    """What every built-in student shares (DDPG, TD3): the actor and critic networks and
    optimisers of the ``ddpg`` config group, observation normalisation and acting. Pure and jittable."""

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


def actor_architecture(config) -> dict:
    """The acting policy of an ``ActorCritic`` student as ``policy.npz`` describes it for its NumPy loader
    (``metapg_jax.host.policy``): an MLP on clipped normalised observations, ReLU hidden layers (LayerNorm
    after each Dense if set), tanh output; the parameters are ``dense_<i>``, ``ln_<i>`` and ``out``."""
    c = config.ddpg
    return {"kind": "mlp", "hidden": list(c.hidden), "layer_norm": bool(c.layer_norm), "layer_norm_epsilon": 1e-6,
            "normalize_obs": bool(c.normalize_obs), "obs_clip": float(c.obs_clip), "activation": "relu",
            "output": "tanh"}
