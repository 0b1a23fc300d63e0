"""Colored (pink) action noise (Eberhard, Hollenstein, Pinneri and Martius, ICLR 2023, "Pink Noise Is All You
Need"): ``--noise=pink`` for ``--method=ddpg`` (a = clip(mu(s) + stddev * z_t)) and ``--method=own`` (a
stochastic student's sampling noise, SAC: tanh(mean + std * z_t)).

At every episode start each seed draws, per action dimension, a Gaussian sequence z_0..z_{T-1} of the task's
episode length T whose power spectrum falls as 1/f^beta (beta = 0 white, 1 pink, 2 red/Brownian) and uses
z_t at the episode's step t. The sequence and the step index are the seed's explorer state, so a chunked or
resumed run draws the same noise as one scan.

Drawing a sequence (as the reference's ``colorednoise.powerlaw_psd_gaussian``): frequencies f_k = k/T,
k = 0..T/2; amplitudes w_k = max(f_k, 1/T)^(-beta/2) (the DC term takes the lowest frequency's);
real and imaginary parts N(0, w_k^2), the DC and (T even) Nyquist terms real and scaled by sqrt(2); an
inverse real FFT. Defaults: ``pink.beta = 1`` (the paper's recommendation), the scale ``noise.stddev`` (0.2
under the paper preset, 0.1 under the modern one, as for Gaussian noise).

Differences from the reference package (``pink-noise-rl``, NumPy/PyTorch): the sequence is divided by its
exact expected standard deviation, (2/T^2 (w_0^2 + 2 sum_{0<k<T/2} w_k^2 + w_{T/2}^2))^(1/2), DC term
included, so every step's variance is stddev^2 exactly in expectation (the reference normalises without the
DC term, a slightly larger variance for beta > 0); a new sequence is drawn at every episode start and never in
between (the reference refills when a sequence runs out and its action noise resets at episode ends); the
sequence length is the task's time limit (the reference's default ``seq_len`` is 1000 for every task).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
from flax import struct

from metapg_jax import action_noise, strategy


@dataclasses.dataclass(frozen=True)
class PinkConfig:
    """Colored noise's exponent (the ``pink`` group); its scale is ``noise.stddev``."""

    beta: float = 1.0   # power spectrum ~ 1/f^beta: 0 white, 1 pink (Eberhard et al.'s default), 2 red


@struct.dataclass
class ColoredState:
    sequence: jax.Array   # (T, action_size): this episode's unit-variance colored noise
    step: jax.Array       # int32: the episode's next step


def _init(config, action_size: int) -> ColoredState:
    return ColoredState(sequence=jnp.zeros((config.episode_length, action_size), jnp.float32),
                        step=jnp.zeros((), jnp.int32))


def _episode_start(config, state: ColoredState, key: jax.Array) -> ColoredState:
    length, size = state.sequence.shape
    # the sequence's draw (module docstring), shared with the bandit teacher's colored D0
    return ColoredState(sequence=action_noise.colored_sequence(key, config.pink.beta, length, size),
                        step=jnp.zeros((), jnp.int32))


def _sample(config, state: ColoredState, key: jax.Array):
    length = state.sequence.shape[0]
    z = state.sequence[jnp.minimum(state.step, length - 1)]
    return z, config.noise.stddev, state.replace(step=state.step + 1)


def _validate(config) -> None:
    action_noise.check_beta("pink.beta", config.pink.beta)


NAME = "pink"
strategy.register_group(NAME, PinkConfig)
action_noise.register_kind(action_noise.NoiseKind(
    NAME, _init, _sample, episode_start=_episode_start, policy_noise=True, validate=_validate,
    summary="colored noise ~ 1/f^beta, a sequence per episode and action dimension (Eberhard et al., 2023)"))
