"""The DDPG student (Lillicrap et al., 2016) as in the 2018 OpenAI-baselines DDPG.

Per update, on a minibatch (s, a, r, s', terminated) with observations
normalised by the running normaliser:

    y      = r + gamma * (1 - terminated) * Q'(s', mu'(s'))       (targets: no gradient)
    L_Q    = mean (Q(s, a) - y)^2 + critic_l2 * sum ||W_hidden||^2 / 2
    L_mu   = -mean Q(s, mu(s))                                       (the paper's section 3.2)
    theta' <- tau * theta + (1 - tau) * theta'                       (both targets)

Both gradients are taken at the same (pre-update) parameters and applied
together, as baselines does. Truncated transitions bootstrap; terminated ones
do not.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import optax
from flax import struct

from metapg_jax import strategy
from metapg_jax.actor_critic import ActorCritic
from metapg_jax.networks import is_hidden_kernel_path
from metapg_jax.types import Params, Transition


@struct.dataclass
class StudentState:
    actor: Params
    critic: Params
    target_actor: Params
    target_critic: Params
    actor_opt: optax.OptState
    critic_opt: optax.OptState


@dataclasses.dataclass(frozen=True)
class DDPG(ActorCritic):
    """The DDPG student (module docstring); all methods are pure and jittable."""

    def init(self, key: jax.Array) -> StudentState:
        k_actor, k_critic = jax.random.split(key)
        obs = jnp.zeros((self.obs_size,), jnp.float32)
        act = jnp.zeros((self.action_size,), jnp.float32)
        actor = self.actor_net.init(k_actor, obs)
        critic = self.critic_net.init(k_critic, obs, act)
        return StudentState(actor=actor, critic=critic, target_actor=actor, target_critic=critic,
                            actor_opt=self.actor_opt.init(actor), critic_opt=self.critic_opt.init(critic))

    # -- learning ---------------------------------------------------------------
    def critic_loss(self, critic: Params, student: StudentState, normalizer, batch: Transition):
        obs = self.normalize(normalizer, batch.obs)
        next_obs = self.normalize(normalizer, batch.next_obs)
        next_q = self.critic_net.apply(student.target_critic, next_obs,
                                       self.actor_apply(student.target_actor, next_obs))
        # The TD target is a fixed regression target (deliberate stop_gradient).
        target = jax.lax.stop_gradient(batch.reward + self.cfg.gamma * (1.0 - batch.terminated) * next_q)
        q = self.critic_net.apply(critic, obs, batch.action)
        td_loss = jnp.mean(jnp.square(q - target))
        l2 = sum(jnp.sum(jnp.square(w)) for path, w in jax.tree_util.tree_leaves_with_path(critic)
                 if is_hidden_kernel_path(path))
        return td_loss + 0.5 * self.cfg.critic_l2 * l2, {"q_mean": jnp.mean(q), "td_loss": td_loss}

    def actor_loss(self, actor: Params, student: StudentState, normalizer, batch: Transition):
        obs = self.normalize(normalizer, batch.obs)
        return -jnp.mean(self.critic_net.apply(student.critic, obs, self.actor_apply(actor, obs)))

    def update(self, student: StudentState, normalizer, batch: Transition) -> tuple[StudentState, dict]:
        """One DDPG update on a minibatch: critic and actor from the same parameters, then targets."""
        (c_loss, aux), c_grad = jax.value_and_grad(self.critic_loss, has_aux=True)(
            student.critic, student, normalizer, batch)
        a_loss, a_grad = jax.value_and_grad(self.actor_loss)(student.actor, student, normalizer, batch)
        c_upd, critic_opt = self.critic_opt.update(c_grad, student.critic_opt, student.critic)
        a_upd, actor_opt = self.actor_opt.update(a_grad, student.actor_opt, student.actor)
        critic = optax.apply_updates(student.critic, c_upd)
        actor = optax.apply_updates(student.actor, a_upd)
        tau = self.cfg.tau
        soft = lambda t, o: (1.0 - tau) * t + tau * o
        student = StudentState(
            actor=actor, critic=critic,
            target_actor=jax.tree.map(soft, student.target_actor, actor),
            target_critic=jax.tree.map(soft, student.target_critic, critic),
            actor_opt=actor_opt, critic_opt=critic_opt)
        return student, {"critic_loss": c_loss, "actor_loss": a_loss, **aux}


strategy.register_student(
    "ddpg", lambda config, obs_size, action_size: DDPG(config.ddpg, obs_size, action_size),
    summary="DDPG (Lillicrap et al., 2016), as in the 2018 OpenAI baselines")
