"""The TD3 student (Fujimoto, van Hoof and Meger, 2018), with the same interface as DDPG (``metapg_jax.strategies.ddpg``).

Per update, on a minibatch (s, a, r, s', terminated) with observations normalised by the running
normaliser (actions are in [-1, 1], so the action bound is 1):

    a'     = clip(mu'(s') + clip(N(0, policy_noise^2), -noise_clip, noise_clip), -1, 1)   (target smoothing)
    y      = r + gamma * (1 - terminated) * min(Q1'(s', a'), Q2'(s', a'))               (no gradient)
    L_Q    = mean (Q1(s, a) - y)^2 + mean (Q2(s, a) - y)^2 (+ critic_l2 on both critics' hidden kernels)
    every ``policy_delay``-th update, after the critics' step:
    L_mu   = -mean Q1(s, mu(s));   theta' <- tau * theta + (1 - tau) * theta'   (actor and both critics)

as the authors' reference code does it (the actor's loss uses the critics just updated; the targets
move only on actor updates). The networks, optimisers, batch size, tau and gamma are the ``ddpg``
config group's (the actor-critic settings every student uses); ``td3`` holds ``policy_noise``,
``noise_clip`` and ``policy_delay``. The state carries its own PRNG key (the smoothing noise) and
update count, so ``update(state, normalizer, batch)`` has DDPG's signature, and the look-ahead copy of
Algorithm 1 copies them with the rest.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import optax
from flax import struct

from metapg_jax import strategy
from metapg_jax.actor_critic import ActorCritic
from metapg_jax.seeds import per_seed_cond
from metapg_jax.types import Params, Transition


@dataclasses.dataclass(frozen=True)
class TD3Config:
    """TD3's own settings (Fujimoto et al., 2018; in normalised action units); the networks, optimisers,
    batch, tau and gamma are the ``ddpg`` group's."""

    policy_noise: float = 0.2      # target-policy smoothing noise stddev
    noise_clip: float = 0.5        # ... clipped to +-noise_clip
    policy_delay: int = 2          # actor and target updates every policy_delay critic updates


@struct.dataclass
class TD3State:
    actor: Params
    critic: Params          # {"q1": ..., "q2": ...}
    target_actor: Params
    target_critic: Params
    actor_opt: optax.OptState
    critic_opt: optax.OptState
    key: jax.Array          # for the target-policy smoothing noise
    step: jax.Array         # int32: critic updates so far (the actor moves when step % policy_delay == 0)
    actor_loss: jax.Array   # the latest actor update's loss (reported at every update)


@dataclasses.dataclass(frozen=True)
class TD3(ActorCritic):
    """The TD3 student (module docstring): DDPG's networks, optimisers and acting
    (``metapg_jax.actor_critic.ActorCritic``), its own state and update. Pure and jittable."""

    td3: TD3Config = TD3Config()

    def init(self, key: jax.Array) -> TD3State:
        actor, critic, k_state = self.init_actor_and_twin_critics(key)
        return TD3State(actor=actor, critic=critic, target_actor=actor, target_critic=critic,
                        actor_opt=self.actor_opt.init(actor), critic_opt=self.critic_opt.init(critic),
                        key=k_state, step=jnp.zeros((), jnp.int32), actor_loss=jnp.zeros((), jnp.float32))

    # -- learning --------------------------------------------------------------------
    def smoothed_action(self, target_actor: Params, next_obs_normalized: jax.Array, key: jax.Array) -> jax.Array:
        """a' = clip(mu'(s') + clip(N(0, policy_noise^2), -noise_clip, noise_clip), -1, 1)."""
        mu = self.actor_apply(target_actor, next_obs_normalized)
        noise = jnp.clip(self.td3.policy_noise * jax.random.normal(key, mu.shape), -self.td3.noise_clip,
                         self.td3.noise_clip)
        return jnp.clip(mu + noise, -1.0, 1.0)

    def target(self, state: TD3State, normalizer, batch: Transition, key: jax.Array) -> jax.Array:
        """The clipped double-Q target with target-policy smoothing (no gradient)."""
        next_obs = self.normalize(normalizer, batch.next_obs)
        next_action = self.smoothed_action(state.target_actor, next_obs, key)
        q1 = self.critic_net.apply(state.target_critic["q1"], next_obs, next_action)
        q2 = self.critic_net.apply(state.target_critic["q2"], next_obs, next_action)
        return jax.lax.stop_gradient(batch.reward + self.cfg.gamma * (1.0 - batch.terminated) * jnp.minimum(q1, q2))

    critic_loss = ActorCritic.twin_critic_loss

    def actor_loss(self, actor: Params, critic: Params, normalizer, batch: Transition):
        obs = self.normalize(normalizer, batch.obs)
        return -jnp.mean(self.critic_net.apply(critic["q1"], obs, self.actor_apply(actor, obs)))

    def update(self, state: TD3State, normalizer, batch: Transition) -> tuple[TD3State, dict]:
        """One TD3 update: both critics; every ``policy_delay``-th time also the actor and the targets."""
        key, k_noise = jax.random.split(state.key)
        target = self.target(state, normalizer, batch, k_noise)
        (c_loss, aux), c_grad = jax.value_and_grad(self.critic_loss, has_aux=True)(
            state.critic, normalizer, batch, target)
        c_upd, critic_opt = self.critic_opt.update(c_grad, state.critic_opt, state.critic)
        critic = optax.apply_updates(state.critic, c_upd)
        state = state.replace(critic=critic, critic_opt=critic_opt, key=key)

        def delayed(s: TD3State) -> TD3State:
            a_loss, a_grad = jax.value_and_grad(self.actor_loss)(s.actor, s.critic, normalizer, batch)
            a_upd, actor_opt = self.actor_opt.update(a_grad, s.actor_opt, s.actor)
            actor = optax.apply_updates(s.actor, a_upd)
            tau = self.cfg.tau
            soft = lambda t, o: (1.0 - tau) * t + tau * o
            return s.replace(actor=actor, actor_opt=actor_opt, actor_loss=a_loss,
                             target_actor=jax.tree.map(soft, s.target_actor, actor),
                             target_critic=jax.tree.map(soft, s.target_critic, s.critic))

        # Every seed is at the same update count, so this is one real conditional for the seed batch
        # (per_seed_cond), not a select that computes the actor's update at every step.
        due = state.step % self.td3.policy_delay == 0
        state = per_seed_cond(due, delayed, lambda s: s, state)
        state = state.replace(step=state.step + 1)
        return state, {"critic_loss": c_loss, "actor_loss": state.actor_loss, **aux}


def _schedule(config):
    """Under the modern preset: the TD3 authors' 25k uniformly random steps before the first update (their
    ``start_timesteps``). An explorer that explores from the first step (the teacher) sets its own warm-up
    after this."""
    if config.preset != "modern":
        return config
    return config.replace(run=dataclasses.replace(config.run, warmup_steps=25_000))


def _validate(config) -> None:
    t = config.td3
    if t.policy_noise < 0 or t.noise_clip < 0 or t.policy_delay <= 0:
        raise ValueError("td3.policy_noise and td3.noise_clip must be >= 0 and td3.policy_delay positive")


strategy.register_student(
    "td3", lambda config, obs_size, action_size: TD3(config.ddpg, obs_size, action_size, td3=config.td3),
    group=TD3Config, schedule=_schedule, validate=_validate,
    summary="TD3 (Fujimoto et al., 2018): twin critics, target smoothing, delayed actor")
