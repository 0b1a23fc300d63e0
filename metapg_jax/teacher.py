"""The exploration teacher pi_e and its meta-policy-gradient update (paper section 4), and the registry of
teacher designs (``meta.teacher``).

The paper's two designs (its section 4, both required) are here:

* ``independent``: pi_e(a|s) = N(f(s), diag sigma(s)^2) with a mean MLP and a
  log-std MLP of its own (64-64 each, LayerNorm as the paper's networks),
  independent of the student. The paper's best design.
* ``variance``: pi_e(a|s) = N(mu_student(s), diag sigma^2): the mean is the
  student's actor under ``stop_gradient`` (the teacher never changes the
  student), only sigma is learned: a state-independent vector
  (``state_dependent_std=False``, the paper's sigma^2 I) or a log-std MLP.

Inputs are the observations normalised by the student's running normaliser
(ours: the paper does not say). The log-std is squashed into
[min_log_std, max_log_std] with a scaled tanh, and starts at ``init_log_std``.
``sample`` returns the unclipped Gaussian sample (for the log-probability) and
the sample clipped to [-1, 1] (for the environment and the buffer).

REINFORCE (the paper's eq. 5): theta_e <- theta_e + eta * R(D0) * sum_t grad log pi_e(a_t | s_t),
with Adam (lr 1e-4), ``teacher_steps`` steps per cycle on the same D0.

Other designs are one file each in ``metapg_jax.strategies`` that subclasses :class:`Teacher` and calls
:func:`register_design` (:func:`designs` lists them); Algorithm 1's cycle
(``metapg_jax.strategies.meta``) asks :func:`make` for the design that ``meta.teacher`` names and uses only
this class's methods: ``init``, ``begin_cycle``, ``d0_carry``, ``sample_step`` (``sample``'s by default), ``end_d0``,
``update``, ``diagnostics``, ``normalize_reward``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable

import jax
import jax.numpy as jnp
import optax
from flax import struct

from metapg_jax.networks import MLP
from metapg_jax.types import Params

_LOG_2PI_E = math.log(2 * math.pi * math.e)


@struct.dataclass
class TeacherState:
    params: Params
    opt: optax.OptState
    r_hat: jax.Array          # R_hat(pi) carried to the next cycle (NaN before the first estimate)
    reward_count: jax.Array   # running statistics of the meta reward (optional normalisation)
    reward_mean: jax.Array
    reward_m2: jax.Array


@dataclasses.dataclass(frozen=True)
class Teacher:
    """The Gaussian teacher of the paper's designs, and the base class of every other design: a design overrides
    what differs (its parameters, its distribution, how it learns) and keeps the rest."""

    cfg: Any      # the meta group (metapg_jax.strategies.meta.MetaConfig)
    student: Any  # the learner whose actor the variance teacher's mean is (metapg_jax.loop: the student interface)

    @property
    def action_size(self) -> int:
        return self.student.action_size

    @property
    def optimizer(self) -> optax.GradientTransformation:
        return optax.adam(self.cfg.lr)

    # The raw network output is squashed: log_std = lo + (hi - lo) * (tanh(raw) + 1) / 2.
    def squash_log_std(self, raw: jax.Array) -> jax.Array:
        lo, hi = self.cfg.min_log_std, self.cfg.max_log_std
        return lo + (hi - lo) * 0.5 * (jnp.tanh(raw) + 1.0)

    def raw_init_log_std(self) -> float:
        lo, hi = self.cfg.min_log_std, self.cfg.max_log_std
        x = 2.0 * (self.cfg.init_log_std - lo) / (hi - lo) - 1.0
        # In float64 for the config's numbers; in float32 where a sweep traces them (metapg_jax.sweep).
        return math.atanh(x) if isinstance(x, float) else jnp.arctanh(x)

    def _mean_net(self) -> MLP:
        return MLP(self.action_size, tuple(self.cfg.hidden), self.cfg.layer_norm)

    def _log_std_net(self) -> MLP:
        return MLP(self.action_size, tuple(self.cfg.hidden), self.cfg.layer_norm, bias_init=self.raw_init_log_std())

    def init(self, key: jax.Array) -> TeacherState:
        """Parameters: {'mean': MLP, 'log_std': MLP} (independent), {'log_std': MLP or vector} (variance)."""
        obs = jnp.zeros((self.student.obs_size,), jnp.float32)
        k_mean, k_std = jax.random.split(key)
        if self.cfg.teacher == "variance" and not self.cfg.state_dependent_std:
            params = {"log_std": jnp.full((self.action_size,), self.raw_init_log_std(), jnp.float32)}
        else:
            params = {"log_std": self._log_std_net().init(k_std, obs)}
        if self.cfg.teacher == "independent":
            params["mean"] = self._mean_net().init(k_mean, obs)
        return self.new_state(params, self.optimizer.init(params))

    @staticmethod
    def new_state(params: Params, opt: Any) -> TeacherState:
        """A design's initial state: its parameters and optimiser state, no R_hat(pi) yet, no reward statistics."""
        zero = jnp.zeros((), jnp.float32)
        return TeacherState(params=params, opt=opt, r_hat=jnp.full((), jnp.nan, jnp.float32),
                            reward_count=zero, reward_mean=zero, reward_m2=zero)

    def begin_cycle(self, state: TeacherState, key: jax.Array) -> TeacherState:
        """Before the cycle's D0: a design that chooses something per cycle (the bandit's arm) does it here."""
        return state

    def distribution(self, params: Params, student_actor: Params, obs_normalized: jax.Array):
        """(mean, log_std) of pi_e(.|s) for normalised observations (any leading axes)."""
        if self.cfg.teacher == "independent":
            mean = self._mean_net().apply(params["mean"], obs_normalized)
        else:
            # Variance teacher: the student's action is the mean; no gradient reaches the student.
            mean = jax.lax.stop_gradient(self.student.actor_apply(student_actor, obs_normalized))
        if isinstance(params["log_std"], dict):
            raw = self._log_std_net().apply(params["log_std"], obs_normalized)
        else:
            raw = jnp.broadcast_to(params["log_std"], mean.shape)
        return mean, self.squash_log_std(raw)

    def sample(self, params, student_actor, obs_normalized, key):
        """(clipped action for the env, unclipped Gaussian sample for the log-prob)."""
        mean, log_std = self.distribution(params, student_actor, obs_normalized)
        raw = mean + jnp.exp(log_std) * jax.random.normal(key, mean.shape)
        return jnp.clip(raw, -1.0, 1.0), raw

    # D0's rollout carries a per-step state across steps and cycles where a design needs one (the colored bandit's
    # noise sequence); the paper's designs and every other have none: D0's actions are ``sample``'s.
    def d0_carry(self, state: TeacherState) -> Any:
        """The state D0's rollout starts from (kept by ``end_d0`` for the next cycle's D0); None: no state."""
        return None

    def sample_step(self, params, carry, student_actor, obs_normalized, first, key):
        """One step of D0: (clipped action, unclipped sample, carry); ``first`` marks an episode's first step."""
        action, raw = self.sample(params, student_actor, obs_normalized, key)
        return action, raw, carry

    def end_d0(self, state: TeacherState, carry: Any) -> TeacherState:
        """``state`` after D0's rollout, which ended with ``carry``."""
        return state

    def log_prob(self, params, student_actor, obs_normalized, raw_action) -> jax.Array:
        """log pi_e(a|s) of the unclipped sample, summed over action dimensions."""
        mean, log_std = self.distribution(params, student_actor, obs_normalized)
        z = (raw_action - mean) * jnp.exp(-log_std)
        return jnp.sum(-0.5 * jnp.square(z) - log_std - 0.5 * math.log(2 * math.pi), axis=-1)

    def entropy(self, log_std: jax.Array) -> jax.Array:
        return jnp.sum(log_std + 0.5 * _LOG_2PI_E, axis=-1)

    def diagnostics(self, params: Params, student_actor: Params, obs_normalized: jax.Array) -> dict:
        """The cycle's teacher metrics on D0's observations: mean log-std of pi_e, its mean entropy (nats), and
        the RMS distance of its mean (clipped to the action range) from the student's action: how far what the
        teacher learned moves it from the student, its noise left out (the cycle's ``teacher_student_distance``
        is D0's actions', noise included)."""
        mean, log_std = self.distribution(params, student_actor, obs_normalized)
        student = self.student.actor_apply(student_actor, obs_normalized)
        return {"teacher_log_std": jnp.mean(log_std), "teacher_entropy": jnp.mean(self.entropy(log_std)),
                "teacher_mean_distance": jnp.sqrt(jnp.mean(jnp.square(jnp.clip(mean, -1.0, 1.0) - student)))}

    def reinforce_loss(self, params, student_actor, obs_normalized, raw_actions, meta_reward):
        """-R(D0) * sum_t log pi_e(a_t|s_t): its gradient is minus the paper's eq. 5 ascent direction."""
        logp = self.log_prob(params, student_actor, obs_normalized, raw_actions)
        return -jax.lax.stop_gradient(meta_reward) * jnp.sum(logp)

    def update(self, state: TeacherState, student_actor, obs_normalized, raw_actions, meta_reward):
        """``teacher_steps`` Adam steps on the REINFORCE loss of one D0."""

        def step(c, _):
            params, opt = c
            grad = jax.grad(self.reinforce_loss)(params, student_actor, obs_normalized, raw_actions, meta_reward)
            upd, opt = self.optimizer.update(grad, opt, params)
            return (optax.apply_updates(params, upd), opt), None

        (params, opt), _ = jax.lax.scan(step, (state.params, state.opt), None, length=self.cfg.teacher_steps)
        return state.replace(params=params, opt=opt)

    def normalize_reward(self, state: TeacherState, reward: jax.Array):
        """Running mean/std normalisation of the meta reward (our addition, off by default)."""
        count = state.reward_count + 1.0
        delta = reward - state.reward_mean
        mean = state.reward_mean + delta / count
        m2 = state.reward_m2 + delta * (reward - mean)
        std = jnp.sqrt(m2 / jnp.maximum(count - 1.0, 1.0))
        normalized = jnp.where(count > 1, (reward - mean) / jnp.maximum(std, 1e-6), 0.0)
        return state.replace(reward_count=count, reward_mean=mean, reward_m2=m2), normalized


# ------------------------------------------------------------------------------------------ the designs by name
# name -> (make(meta group, student, config) -> Teacher, a few words). The paper's two here; the others register
# from their files in metapg_jax.strategies (imported by metapg_jax.strategy.load_builtins).
_DESIGNS: dict[str, tuple[Callable[[Any, Any, Any], Teacher], str]] = {
    "independent": (lambda cfg, student, config: Teacher(cfg, student), "the paper's design (ii): own mean and log-std"),
    "variance": (lambda cfg, student, config: Teacher(cfg, student), "the paper's design (i): the student's mean"),
}


def register_design(name: str, make: Callable[[Any, Any, Any], Teacher], summary: str = "") -> None:
    """Registers a teacher design (``meta.teacher=<name>``): ``make(meta group, student, config) -> Teacher``
    (the whole config for a design that reads a config group of its own)."""
    _DESIGNS[name] = (make, summary)


def designs() -> dict[str, str]:
    """Every registered design: {name: summary}, the paper's first."""
    from metapg_jax import strategy

    strategy.load_builtins()
    return {name: summary for name, (_, summary) in _DESIGNS.items()}


def make(config: Any, student: Any) -> Teacher:
    """The teacher that ``config.meta.teacher`` names, for ``student``."""
    designs()
    return _DESIGNS[config.meta.teacher][0](config.meta, student, config)
