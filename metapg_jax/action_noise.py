"""Action-noise processes: the registry of noise kinds that the acting explorers draw their noise from
(``--noise=<kind>``), and the three plain ones.

A *kind* (:class:`NoiseKind`) is a per-seed process state, an optional ``episode_start`` and a ``sample`` that
gives each step's noise as ``z`` and a ``scale``. The DDPG baselines' explorer (``--method=ddpg``,
``metapg_jax.strategies.noise``) acts with clip(mu(s) + scale * z); a stochastic student's own policy
(``--method=own``, ``metapg_jax.strategies.own``) samples with ``z`` as its noise, for the kinds whose ``z`` is
standard normal at every step (``policy_noise``). The kinds read the ``noise`` config group (the ``ddpg``
explorer's) and, for settings of their own, a group they register (``strategy.register_group``).

Built in here: ``normal`` (z ~ N(0, I), scale ``noise.stddev``), ``ou`` (Ornstein-Uhlenbeck,
x <- x + theta (0 - x) dt + sigma sqrt(dt) N(0, I), reset to 0 at every episode start, as the 2018
OpenAI baselines) and ``none`` (no noise). Each further kind is one file of ``metapg_jax.strategies`` that
calls :func:`register_kind` (colored noise: ``pink.py``; per-episode scales: ``mixed.py``), or a plug-in's.

Adaptive parameter noise (``--noise=adaptive-param``, :data:`PARAMETER_NOISE`; Plappert et al., 2018) is a
value of ``noise.kind`` but not a kind: the ``ddpg`` explorer has it built in (``metapg_jax.strategies.noise``),
for the reasons given here (and nowhere else). A kind's ``sample`` sees its own state and a key, not the
observation or the student, so that both explorers can use its ``z``: added to mu(s), or as a stochastic
policy's sampling noise. Adaptive parameter noise acts with a perturbed copy of the actor, mu~(s): neither mu(s)
plus a ``z`` nor a policy's sampling noise. It draws that copy from the student's actor parameters at every
episode start, and it adapts its stddev on replay minibatches between blocks of the student's updates
(``ActingExplorer.adapt``, every ``adapt_every`` updates). As a kind, it would need ``NoiseKind`` to take the
actor's parameters and function, the observation and replay minibatches, the acting explorer's hooks
(``metapg_jax.strategy.ActingExplorer``), passed through every kind and both explorers for one kind that
``--method=own`` could not use.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable

import jax
import jax.numpy as jnp
import numpy as np

from metapg_jax import strategy
from metapg_jax.config import positive


@dataclasses.dataclass(frozen=True)
class NoiseKind:
    """An action-noise process, chosen with ``--noise=<name>`` (module docstring). Functions of the whole config
    (a kind reads ``config.noise`` and a group of its own), pure and jittable:

    * ``init(config, action_size) -> process``: the per-seed state before the first episode;
    * ``sample(config, process, key) -> (z, scale, process)``: one step's noise ``scale * z``, ``z`` of shape
      ``(action_size,)``;
    * ``episode_start(config, process, key) -> process`` (optional): at the first step of every episode;
    * ``policy_noise``: ``z`` is N(0, 1) at every step and in every dimension and the kind is about ``z``, not its
      scale: a stochastic student can sample with it (``--method=own``);
    * ``validate(config)``: one-line ``ValueError`` for bad values, run when the kind is chosen;
    * ``metrics(config, process) -> dict`` (optional): scalars of the process, added to each cycle's metrics.
    """

    name: str
    init: Callable[[Any, int], Any]
    sample: Callable[[Any, Any, jax.Array], tuple[jax.Array, Any, Any]]
    episode_start: Callable[[Any, Any, jax.Array], Any] | None = None
    policy_noise: bool = False
    validate: Callable[[Any], None] = lambda config: None
    metrics: Callable[[Any, Any], dict] | None = None
    summary: str = ""


_KINDS: dict[str, NoiseKind] = {}
PARAMETER_NOISE = "adaptive-param"   # a value of noise.kind that is not a kind (module docstring)


def register_kind(kind: NoiseKind) -> NoiseKind:
    """Registers an action-noise kind (a name registered again is replaced: a plug-in re-imported)."""
    _KINDS[kind.name] = kind
    return kind


def kinds() -> dict[str, NoiseKind]:
    """Every registered kind (the built-in strategy files' once imported)."""
    strategy.load_builtins()
    return dict(_KINDS)


def kind(name: str) -> NoiseKind:
    """The kind registered as ``name``; a one-line ``ValueError`` naming the valid ones otherwise."""
    known = kinds()
    if name not in known:
        raise ValueError(f"unknown noise {name!r}; valid noises: {', '.join(sorted(known))}")
    return known[name]


# -- a process in an explorer's carry ---------------------------------------------------------------------------
def init(config, action_size: int) -> Any:
    """The chosen kind's (``config.noise.kind``) per-seed state."""
    return kind(config.noise.kind).init(config, action_size)


def episode_start(config, process: Any, key: jax.Array) -> Any:
    start = kind(config.noise.kind).episode_start
    return start(config, process, key) if start else process


def sample(config, process: Any, key: jax.Array) -> tuple[jax.Array, Any, Any]:
    """One step: (z, scale, the new state)."""
    return kind(config.noise.kind).sample(config, process, key)


def metrics(config, process: Any) -> dict:
    """The chosen kind's own per-cycle metrics (none for most)."""
    own = kind(config.noise.kind).metrics
    return own(config, process) if own else {}


def validate(config) -> None:
    """The checks of ``config.noise`` for a kind chosen by an acting explorer."""
    n = config.noise
    if n.kind != "none":
        positive("noise.stddev", n.stddev)
    kind(n.kind).validate(config)


def check_warmup(config) -> None:
    """An acting explorer's run must leave the warm-up of uniformly random actions before its budget ends."""
    run = config.run
    if run.warmup_steps and run.warmup_steps >= run.total_steps:
        raise ValueError(f"run.warmup_steps={run.warmup_steps} is not below the budget of {run.total_steps} "
                         f"env steps: the --method={run.method} run would act at random throughout (lower it with "
                         f"--set run.warmup_steps=N, or raise --steps)")


# -- the plain kinds ---------------------------------------------------------------------------------------------
def _zeros(config, action_size: int) -> jax.Array:
    """A zero vector of the action's shape (the process of kinds without state: it carries the shape)."""
    return jnp.zeros((action_size,), jnp.float32)


def _normal_sample(config, process, key):
    return jax.random.normal(key, process.shape), config.noise.stddev, process


def _ou_sample(config, x, key):
    n = config.noise
    x = x + n.ou_theta * (0.0 - x) * n.ou_dt + n.stddev * jnp.sqrt(n.ou_dt) * jax.random.normal(key, x.shape)
    return x, 1.0, x


def _check_ou(config) -> None:
    n = config.noise
    positive("noise.ou_dt", n.ou_dt)
    if not (math.isfinite(n.ou_theta) and n.ou_theta >= 0):
        raise ValueError(f"noise.ou_theta must be a finite number >= 0, got {n.ou_theta!r}")


register_kind(NoiseKind("normal", _zeros, _normal_sample, policy_noise=True,
                        summary="Gaussian: mu(s) + N(0, stddev^2) at every step"))
register_kind(NoiseKind("ou", _zeros, _ou_sample, episode_start=lambda config, x, key: jnp.zeros_like(x),
                        validate=_check_ou, summary="Ornstein-Uhlenbeck, reset to 0 at every episode start"))
register_kind(NoiseKind("none", _zeros, lambda config, process, key: (process, 0.0, process),
                        summary="no noise: the student's actor"))


# ------------------------------------------------------------------------------------------ colored sequences
# The draw of colored noise (metapg_jax/strategies/pink.py's docstring has the method and its differences from the
# reference package): the pink kind's and the bandit teacher's colored D0's.

def check_beta(name: str, beta) -> None:
    """``ValueError`` (one line) unless ``beta``, the colour of the setting ``name``, is a finite number >= 0."""
    if not (isinstance(beta, (int, float)) and math.isfinite(beta) and beta >= 0):
        raise ValueError(f"{name} must be a finite number >= 0 (0 white, 1 pink, 2 red), got {beta!r}")


def amplitudes(beta: float, length: int) -> np.ndarray:
    """w_k = max(k / T, 1 / T)^(-beta / 2) for k = 0..T/2 (module docstring)."""
    f = np.fft.rfftfreq(length)
    return np.maximum(f, 1.0 / length) ** (-beta / 2.0)


def colored_sequence(key: jax.Array, beta: float, length: int, size: int) -> jax.Array:
    """(length, size) Gaussian noise with power spectrum ~ 1/f^beta along the first axis, each column
    independent, every entry of variance 1 in expectation."""
    w = amplitudes(beta, length)
    k_re, k_im = jax.random.split(key)
    shape = (size, len(w))
    real = jax.random.normal(k_re, shape) * w
    imag = jax.random.normal(k_im, shape) * w
    edges = [0] + ([len(w) - 1] if length % 2 == 0 else [])   # DC and (T even) Nyquist: real coefficients
    imag = imag.at[:, edges].set(0.0)
    real = real.at[:, edges].multiply(math.sqrt(2.0))
    y = jnp.fft.irfft(real + 1j * imag, n=length, axis=-1)
    middle = w[1:-1] if length % 2 == 0 else w[1:]
    edge_power = w[0] ** 2 + (w[-1] ** 2 if length % 2 == 0 else 0.0)
    variance = 2.0 / length ** 2 * (edge_power + 2.0 * np.sum(middle ** 2))
    return (y / math.sqrt(variance)).T.astype(jnp.float32)
