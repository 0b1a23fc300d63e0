"""The SAC student: soft actor-critic (Haarnoja et al., 2018, arXiv 1801.01290) with the automatic temperature of
Haarnoja et al. (2018b, arXiv 1812.05905, section 5), with the same interface as DDPG
(``metapg_jax.strategies.ddpg``) and TD3.

The actor is a squashed Gaussian: one MLP of the ``ddpg`` group's widths outputs (m(s), l(s)) in R^A x R^A,

    log_std(s) = log_std_min + (log_std_max - log_std_min) * (tanh(l(s)) + 1) / 2      (in [min, max])
    u          = m(s) + exp(log_std(s)) * z,   z ~ N(0, I);     a = tanh(u)
    log pi(a|s) = sum_i log N(u_i; m_i, std_i^2) - sum_i log(1 - tanh(u_i)^2)           (change of variables)

with log(1 - tanh(u)^2) = 2 (log 2 - u - softplus(-2u)), exact and finite for every u, as Brax computes it (SB3
and CleanRL take log(1 - tanh(u)^2 + 1e-6) in float32 instead: about 1 nat too high per dimension at |u| = 8,
about 5 at |u| = 10). Evaluation, the teacher's look-ahead rollout D1 and ``policy.npz`` use the deterministic
action tanh(m(s)); ``sample_action(actor, obs, z)`` is tanh(m + std * z) for a given z (``--method=own``
explores with it).

Per update, on a minibatch (s, a, r, s', terminated) with observations normalised by the running normaliser,
with alpha = exp(log_alpha) as the update begins (no gradient) and in this order:

    1. critics:  a' ~ pi(.|s') from the current actor (SAC has no target actor)
                 y   = r + gamma * (1 - terminated) * (min(Q1'(s', a'), Q2'(s', a')) - alpha * log pi(a'|s'))
                 L_Q = mean (Q1(s, a) - y)^2 + mean (Q2(s, a) - y)^2 (+ critic_l2 on the hidden kernels)
                 (y without gradient)
    2. actor:    a~ = tanh(m(s) + std(s) * z) (reparameterised), on the critics just updated
                 L_pi = mean (alpha * log pi(a~|s) - min(Q1(s, a~), Q2(s, a~)))
    3. temperature (``learn_alpha``), with the actor's sample of step 2 (the actor before its step):
                 L_alpha = mean (-exp(log_alpha) * (log pi(a~|s) + target_entropy))   (log pi without gradient)
    4. targets:  theta' <- tau * theta + (1 - tau) * theta'   (both critics; every update)

The networks, the actor's and the critics' Adam, batch size, tau, gamma and observation normalisation are the
``ddpg`` group's (every student's actor-critic settings), so the presets need nothing new: ``--preset=paper``
gives SAC the paper's DDPG networks and schedule (64-64 with LayerNorm, action at the critic's second layer,
Adam 1e-4 / 1e-3, batch 64, tau 0.01, critic L2 1e-2, running observation normalisation), a like-for-like
comparison with the DDPG baselines; ``--preset=modern`` is already Haarnoja et al. (2018b)'s setting (256-256,
action at the critic's input, Adam 3e-4, batch 256, tau 0.005, one update per env step), with the core's 5000
uniformly random warm-up steps (CleanRL's ``learning_starts``; an explorer may set its own, as the teacher's
0). ``sac`` holds the temperature and the log-std bounds:

* ``target_entropy_scale`` 1.0: target entropy -scale * |A|, the paper's (2018b) -|A| at scale 1;
* ``init_alpha`` 1.0: log_alpha starts at log(init_alpha); SB3, CleanRL and Brax all start at alpha = 1;
* ``alpha_lr`` 3e-4: the paper's (2018b) learning rate for every network (SB3's too; CleanRL uses 1e-3);
* ``log_std_min``, ``log_std_max`` -5, 2 with the scaled tanh above: CleanRL's (after Yarats' pytorch_sac); SB3
  clamps to [-20, 2]. Under the presets' small last layer l(s) starts near 0, so the
  initial std is exp(-1.5) ~ 0.22;
* ``learn_alpha`` False: a fixed temperature ``init_alpha`` (the first paper's setting).

How this differs from the reference implementations:

* one actor step per critic step, on the critics just stepped, and the temperature stepped last, with the
  sample of the actor's step. SB3 steps the temperature first (its losses use the pre-step alpha, as here;
  its actor also sees the stepped critics); Brax steps the temperature first too (pre-step alpha) but its
  actor sees the critics from before their step; CleanRL delays the actor (two actor and temperature steps
  every second update, each temperature step on a fresh sample of the actor just stepped);
* SB3 differentiates log_alpha * (...) rather than exp(log_alpha) * (...) (same fixed point, another step
  size); here, as CleanRL and Brax (and the paper's J(alpha), written in alpha), the loss has alpha itself;
* observations are normalised by the running normaliser and clipped to +-obs_clip under the paper preset
  (the modern preset does not normalise, as the references), and the paper preset's LayerNorm networks,
  U(-3e-3, 3e-3) last layers and critic L2 apply to SAC too;
* the critics' loss is the sum of the two MSEs (SB3 halves it; CleanRL and TD3's authors sum them).

The paper's teacher (``--method=meta``) works unchanged on SAC: its look-ahead copy of the student is a copy of
this state (key, temperature and optimisers included) trained with these updates, D1 runs the deterministic
tanh(m(s)), and the variance teacher's mean is that same action. SAC explores by sampling its own policy
(``--method=own``); the DDPG baselines' action noise and adaptive parameter noise are not SAC's exploration.
The state carries its own PRNG key (the policy samples), so ``update(state, normalizer, batch)`` has DDPG's
signature.
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import optax
from flax import struct

from metapg_jax import strategy
from metapg_jax.actor_critic import ActorCritic, actor_architecture
from metapg_jax.config import positive
from metapg_jax.networks import MLP
from metapg_jax.types import Params, Transition

_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


@dataclasses.dataclass(frozen=True)
class SACConfig:
    """SAC's own settings (module docstring: defaults and their sources); the networks, the actor's and critics'
    optimisers, batch, tau and gamma are the ``ddpg`` group's."""

    alpha_lr: float = 3e-4              # Adam learning rate of log_alpha (Haarnoja et al. 2018b: 3e-4)
    init_alpha: float = 1.0             # initial temperature (SB3, CleanRL, Brax: 1.0)
    learn_alpha: bool = True            # False: a fixed temperature init_alpha
    target_entropy_scale: float = 1.0   # target entropy = -scale * |A| (2018b: -|A|)
    log_std_min: float = -5.0           # the actor's log-std lies in [log_std_min, log_std_max] (CleanRL)
    log_std_max: float = 2.0


@struct.dataclass
class SACState:
    actor: Params           # the MLP of (mean, raw log-std)
    critic: Params          # {"q1": ..., "q2": ...}
    target_critic: Params
    actor_opt: optax.OptState
    critic_opt: optax.OptState
    log_alpha: jax.Array    # float32 scalar: log of the temperature
    alpha_opt: optax.OptState
    key: jax.Array          # for the policy samples of the updates


def log_one_minus_tanh_sq(u: jax.Array) -> jax.Array:
    """log(1 - tanh(u)^2) = 2 (log 2 - u - softplus(-2u)): exact for every u (no epsilon)."""
    return 2.0 * (math.log(2.0) - u - jax.nn.softplus(-2.0 * u))


def squashed_gaussian_log_prob(u: jax.Array, mean: jax.Array, log_std: jax.Array) -> jax.Array:
    """log pi(tanh(u)) for the pre-squash u ~ N(mean, exp(log_std)^2): the Gaussian's log-density minus the log
    of tanh's Jacobian, summed over the last (action) axis."""
    gaussian = -0.5 * jnp.square((u - mean) * jnp.exp(-log_std)) - log_std - _LOG_SQRT_2PI
    return jnp.sum(gaussian - log_one_minus_tanh_sq(u), axis=-1)


@dataclasses.dataclass(frozen=True)
class SAC(ActorCritic):
    """The SAC student (module docstring): the ``ddpg`` group's critics, optimisers and normalisation
    (``metapg_jax.actor_critic.ActorCritic``), a squashed-Gaussian actor, a learned temperature. Pure and
    jittable."""

    sac: SACConfig = SACConfig()

    @property
    def actor_net(self) -> MLP:
        """(mean, raw log-std) of the squashed Gaussian: 2 * action_size outputs."""
        return MLP(2 * self.action_size, tuple(self.cfg.hidden), self.cfg.layer_norm, self.cfg.final_init)

    @property
    def alpha_opt(self) -> optax.GradientTransformation:
        return optax.adam(self.sac.alpha_lr)

    @property
    def target_entropy(self) -> float:
        return -self.sac.target_entropy_scale * self.action_size

    def init(self, key: jax.Array) -> SACState:
        actor, critic, k_state = self.init_actor_and_twin_critics(key)
        log_alpha = jnp.asarray(math.log(self.sac.init_alpha), jnp.float32)
        return SACState(actor=actor, critic=critic, target_critic=critic, actor_opt=self.actor_opt.init(actor),
                        critic_opt=self.critic_opt.init(critic), log_alpha=log_alpha,
                        alpha_opt=self.alpha_opt.init(log_alpha), key=k_state)

    # -- the policy ------------------------------------------------------------------
    def distribution(self, actor: Params, obs_normalized: jax.Array) -> tuple[jax.Array, jax.Array]:
        """(mean, log_std) of the pre-squash Gaussian, log_std squashed into [log_std_min, log_std_max]."""
        out = self.actor_net.apply(actor, obs_normalized)
        mean, raw = out[..., :self.action_size], out[..., self.action_size:]
        lo, hi = self.sac.log_std_min, self.sac.log_std_max
        return mean, lo + 0.5 * (hi - lo) * (jnp.tanh(raw) + 1.0)

    def actor_apply(self, actor: Params, obs_normalized: jax.Array) -> jax.Array:
        """The deterministic action tanh(mean): evaluation, D1, export (``deterministic_policy`` uses it)."""
        return jnp.tanh(self.distribution(actor, obs_normalized)[0])

    def sample_action(self, actor: Params, obs_normalized: jax.Array, z: jax.Array) -> jax.Array:
        """tanh(mean + std * z) for the given standard-normal ``z`` (white or colored; shape (action_size,))."""
        mean, log_std = self.distribution(actor, obs_normalized)
        return jnp.tanh(mean + jnp.exp(log_std) * z)

    def sample_and_log_prob(self, actor: Params, obs_normalized: jax.Array,
                            key: jax.Array) -> tuple[jax.Array, jax.Array]:
        """A reparameterised sample a = tanh(mean + std * z) per row and its log pi(a|s)."""
        mean, log_std = self.distribution(actor, obs_normalized)
        u = mean + jnp.exp(log_std) * jax.random.normal(key, mean.shape, mean.dtype)
        return jnp.tanh(u), squashed_gaussian_log_prob(u, mean, log_std)

    # -- learning --------------------------------------------------------------------
    def target(self, state: SACState, normalizer, batch: Transition, alpha: jax.Array, key: jax.Array) -> jax.Array:
        """The soft clipped double-Q target, a' from the current actor (no gradient)."""
        next_obs = self.normalize(normalizer, batch.next_obs)
        next_action, next_log_prob = self.sample_and_log_prob(state.actor, next_obs, key)
        q1 = self.critic_net.apply(state.target_critic["q1"], next_obs, next_action)
        q2 = self.critic_net.apply(state.target_critic["q2"], next_obs, next_action)
        soft_v = jnp.minimum(q1, q2) - alpha * next_log_prob
        return jax.lax.stop_gradient(batch.reward + self.cfg.gamma * (1.0 - batch.terminated) * soft_v)

    critic_loss = ActorCritic.twin_critic_loss

    def actor_loss(self, actor: Params, critic: Params, normalizer, batch: Transition, alpha: jax.Array,
                   key: jax.Array):
        """L_pi = mean(alpha log pi(a~|s) - min Q(s, a~)); its aux is log pi(a~|s) (the temperature's input)."""
        obs = self.normalize(normalizer, batch.obs)
        action, log_prob = self.sample_and_log_prob(actor, obs, key)
        q = jnp.minimum(self.critic_net.apply(critic["q1"], obs, action),
                        self.critic_net.apply(critic["q2"], obs, action))
        return jnp.mean(alpha * log_prob - q), log_prob

    def alpha_loss(self, log_alpha: jax.Array, log_prob: jax.Array) -> jax.Array:
        """L_alpha = mean(-alpha (log pi + target_entropy)): alpha falls while the entropy is above the target."""
        return jnp.mean(-jnp.exp(log_alpha) * jax.lax.stop_gradient(log_prob + self.target_entropy))

    def temperature_step(self, log_alpha: jax.Array, alpha_opt: optax.OptState, log_prob: jax.Array):
        """One Adam step of ``alpha_loss`` (none with ``learn_alpha=False``). Returns (log_alpha, opt, loss)."""
        loss, grad = jax.value_and_grad(self.alpha_loss)(log_alpha, log_prob)
        if not self.sac.learn_alpha:
            return log_alpha, alpha_opt, loss
        upd, alpha_opt = self.alpha_opt.update(grad, alpha_opt, log_alpha)
        return optax.apply_updates(log_alpha, upd), alpha_opt, loss

    def update(self, state: SACState, normalizer, batch: Transition) -> tuple[SACState, dict]:
        """One SAC update: critics, actor (on the new critics), temperature, critic targets (module docstring)."""
        key, k_next, k_pi = jax.random.split(state.key, 3)
        # The temperature as the update begins, for both losses (its own step comes last).
        alpha = jax.lax.stop_gradient(jnp.exp(state.log_alpha))

        target = self.target(state, normalizer, batch, alpha, k_next)
        (c_loss, aux), c_grad = jax.value_and_grad(self.critic_loss, has_aux=True)(
            state.critic, normalizer, batch, target)
        c_upd, critic_opt = self.critic_opt.update(c_grad, state.critic_opt, state.critic)
        critic = optax.apply_updates(state.critic, c_upd)

        (a_loss, log_prob), a_grad = jax.value_and_grad(self.actor_loss, has_aux=True)(
            state.actor, critic, normalizer, batch, alpha, k_pi)
        a_upd, actor_opt = self.actor_opt.update(a_grad, state.actor_opt, state.actor)
        actor = optax.apply_updates(state.actor, a_upd)

        log_alpha, alpha_opt, alpha_loss = self.temperature_step(state.log_alpha, state.alpha_opt, log_prob)

        tau = self.cfg.tau
        soft = lambda t, o: (1.0 - tau) * t + tau * o
        state = state.replace(actor=actor, critic=critic, target_critic=jax.tree.map(soft, state.target_critic, critic),
                              actor_opt=actor_opt, critic_opt=critic_opt, log_alpha=log_alpha, alpha_opt=alpha_opt,
                              key=key)
        return state, {"critic_loss": c_loss, "actor_loss": a_loss, "alpha_loss": alpha_loss, "alpha": alpha,
                       "entropy": -jnp.mean(log_prob), **aux}


def _architecture(config) -> dict:
    """``policy.npz``'s description: the ``ActorCritic`` actor's MLP, whose last layer has 2 * |A| columns
    (mean, raw log-std); the action is tanh of the first |A| (``output='tanh-mean'``)."""
    return {**actor_architecture(config), "output": "tanh-mean"}


def _validate(config) -> None:
    s = config.sac
    positive("sac.alpha_lr", s.alpha_lr)
    positive("sac.init_alpha", s.init_alpha)
    if not (math.isfinite(s.target_entropy_scale) and math.isfinite(s.log_std_min) and math.isfinite(s.log_std_max)):
        raise ValueError("sac.target_entropy_scale, sac.log_std_min and sac.log_std_max must be finite")
    if not s.log_std_min < s.log_std_max:
        raise ValueError(f"sac.log_std_min ({s.log_std_min}) must be smaller than sac.log_std_max ({s.log_std_max})")


strategy.register_student(
    "sac", lambda config, obs_size, action_size: SAC(config.ddpg, obs_size, action_size, sac=config.sac),
    group=SACConfig, validate=_validate, architecture=_architecture, stochastic=True,
    summary="SAC (Haarnoja et al., 2018): twin critics, squashed Gaussian actor, automatic temperature")
