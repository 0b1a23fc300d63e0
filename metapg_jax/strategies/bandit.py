"""The bandit teacher (``--teacher=bandit``, ours): a noise scale learned per cycle instead of a policy.

    pi_e(a|s) = N(mu_student(s), sigma_k^2 I),   sigma_k one of ``bandit.scales``, chosen per cycle

At the start of each cycle (``begin_cycle``) the teacher chooses an arm k: every arm once, in order, then the arm
with the highest value, or with probability ``bandit.epsilon`` a uniformly random one. D0 is the student's action
plus Gaussian noise of that arm's scale (clipped to [-1, 1]). After the look-ahead the arm's value moves toward the
cycle's meta reward, with step max(1 / pulls, ``bandit.step_size``): the sample mean of its first pulls, then an
exponential recency-weighted average, since the best scale changes as the student learns (Sutton and Barto,
2018, section 2.5). A cycle whose meta reward has no baseline yet (the first, unless ``meta.baseline=paired``)
updates nothing. The values are in the meta reward's own units: a normalised meta reward
(``meta.normalize_meta_reward``) is refused, since its scale changes under them. The teacher has no gradient and
no optimiser: ``meta.lr`` and ``meta.teacher_steps`` do not apply.

Why (results/learned/README.md, hypothesis H2): REINFORCE with one scalar reward per cycle cannot fit a 64-64 MLP
(the screen's frozen teacher did as well as the learned one); a choice among a few scales needs only a few
reliable comparisons, as in Schaul et al. (2019) and TOP (Moskovitz et al., 2021), whose bandits choose among a
few behaviour modulations. One scale (``bandit.scales=0.1``) is a fixed-noise control with Algorithm 1's schedule;
``bandit.scales=0`` a control whose D0 is the noiseless student (no exploration data at all).

Colored D0 (``bandit.beta``, ours): 0 (the default) draws white Gaussian noise at every step, as above; beta > 0
takes the noise from a colored sequence with power spectrum ~ 1/f^beta (1 pink, 2 red;
``metapg_jax.action_noise.colored_sequence``, Eberhard et al., 2023), one per episode of the exploring env and
action dimension, drawn at the episode's first step from that step's key and scaled by the cycle's arm. Episodes continue across cycles (the exploring env steps only
in D0), so the sequence and its step are kept in the parameters (``noise``) from one D0 to the next, and a
chunked or resumed run draws the same noise. Each step's noise still has the arm's variance, so the value and the
diagnostics read the arm's scale as for white noise. ``bandit.scales=0.1 bandit.beta=1`` is the "student + pink
noise" control of a colored D0 in Algorithm 1's cycle.
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp

from metapg_jax import strategy, teacher
from metapg_jax.action_noise import check_beta, colored_sequence


@dataclasses.dataclass(frozen=True)
class BanditConfig:
    """The bandit teacher's arms and its choice rule (the ``bandit`` group; ours)."""

    scales: tuple[float, ...] = (0.05, 0.1, 0.2, 0.4)  # Gaussian noise scales (TD3's 0.1, half, twice, 4 times it)
    epsilon: float = 0.2      # probability of a uniformly random arm once every arm has been tried
    step_size: float = 0.05   # the values' smallest step (recency weighting)
    beta: float = 0.0         # D0's noise color: 0 white, 1 pink, 2 red (module docstring)


@dataclasses.dataclass(frozen=True)
class BanditTeacher(teacher.Teacher):
    """``teacher.Teacher`` whose parameters are the bandit's state: {'values', 'pulls' (per arm), 'arm'}."""

    bandit: BanditConfig = BanditConfig()
    episode_length: int = 1000   # the exploring env's time limit: a colored sequence's length

    @property
    def scales(self) -> jax.Array:
        return jnp.asarray(self.bandit.scales, jnp.float32)

    def init(self, key: jax.Array) -> teacher.TeacherState:
        k = len(self.bandit.scales)
        params = {"values": jnp.zeros((k,), jnp.float32), "pulls": jnp.zeros((k,), jnp.float32),
                  "arm": jnp.zeros((), jnp.int32)}
        if self.bandit.beta > 0:  # a colored D0's sequence and step, drawn at the exploring env's first step
            params["noise"] = {"sequence": jnp.zeros((self.episode_length, self.action_size), jnp.float32),
                               "step": jnp.zeros((), jnp.int32)}
        return self.new_state(params, ())

    def choose(self, params, key: jax.Array) -> jax.Array:
        """The first arm not yet pulled; once all have been: the best value, or a random arm with prob. epsilon."""
        k_explore, k_arm = jax.random.split(key)
        untried = params["pulls"] == 0
        greedy = jnp.argmax(params["values"])
        random_arm = jax.random.randint(k_arm, (), 0, len(self.bandit.scales))
        chosen = jnp.where(jax.random.uniform(k_explore) < self.bandit.epsilon, random_arm, greedy)
        return jnp.where(jnp.any(untried), jnp.argmax(untried), chosen).astype(jnp.int32)

    def begin_cycle(self, state: teacher.TeacherState, key: jax.Array) -> teacher.TeacherState:
        return state.replace(params={**state.params, "arm": self.choose(state.params, key)})

    def scale(self, params) -> jax.Array:
        return self.scales[params["arm"]]

    def distribution(self, params, student_actor, obs_normalized):
        mean = jax.lax.stop_gradient(self.student.actor_apply(student_actor, obs_normalized))
        # log of the scale, floored at 1e-6 so that the noiseless control's metrics stay finite
        log_std = jnp.log(jnp.maximum(self.scale(params), 1e-6))
        return mean, jnp.broadcast_to(log_std, mean.shape)

    def sample(self, params, student_actor, obs_normalized, key):
        mean, _ = self.distribution(params, student_actor, obs_normalized)
        raw = mean + self.scale(params) * jax.random.normal(key, mean.shape)
        return jnp.clip(raw, -1.0, 1.0), raw

    def d0_carry(self, state):
        return state.params["noise"] if self.bandit.beta > 0 else None

    def sample_step(self, params, carry, student_actor, obs_normalized, first, key):
        if self.bandit.beta == 0:
            return super().sample_step(params, carry, student_actor, obs_normalized, first, key)
        length = carry["sequence"].shape[0]
        sequence = jax.lax.cond(first, lambda: colored_sequence(key, self.bandit.beta, length, self.action_size),
                                lambda: carry["sequence"])
        step = jnp.where(first, 0, carry["step"])
        mean, _ = self.distribution(params, student_actor, obs_normalized)
        raw = mean + self.scale(params) * sequence[jnp.minimum(step, length - 1)]
        return jnp.clip(raw, -1.0, 1.0), raw, {"sequence": sequence, "step": step + 1}

    def end_d0(self, state, carry):
        return state.replace(params={**state.params, "noise": carry}) if self.bandit.beta > 0 else state

    def update(self, state, student_actor, obs_normalized, raw_actions, meta_reward):
        """The chosen arm's value toward the meta reward (no update before the meta reward has a baseline)."""
        p = state.params
        arm, valid = p["arm"], jnp.isfinite(state.r_hat)
        pulls = p["pulls"].at[arm].add(jnp.where(valid, 1.0, 0.0))
        step = jnp.where(valid, jnp.maximum(1.0 / jnp.maximum(pulls[arm], 1.0), self.bandit.step_size), 0.0)
        values = p["values"].at[arm].add(step * (meta_reward - p["values"][arm]))
        return state.replace(params={**p, "values": values, "pulls": pulls})


def _validate(config) -> None:
    b = config.bandit
    if not b.scales or not all(math.isfinite(s) and s >= 0 for s in b.scales):
        raise ValueError(f"bandit.scales must be one or more finite numbers >= 0, got {b.scales!r}")
    if not 0 <= b.epsilon <= 1:
        raise ValueError(f"bandit.epsilon must be in [0, 1], got {b.epsilon!r}")
    check_beta("bandit.beta", b.beta)
    if not 0 < b.step_size <= 1:
        raise ValueError(f"bandit.step_size must be in (0, 1], got {b.step_size!r}")
    if config.meta.teacher == NAME and config.meta.normalize_meta_reward:
        raise ValueError("the bandit teacher learns from the meta reward itself: meta.normalize_meta_reward=true "
                         "does not apply to it")


NAME = "bandit"
strategy.register_group(NAME, BanditConfig, validate=_validate)
teacher.register_design(NAME, lambda cfg, student, config: BanditTeacher(cfg, student, config.bandit,
                                                                          config.episode_length),
                        "Gaussian noise around the student, its scale chosen per cycle by an epsilon-greedy bandit")
