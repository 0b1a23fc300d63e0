"""Exploration noise of the DDPG baseline: Gaussian, Ornstein-Uhlenbeck, adaptive parameter noise, and the
registry of action-noise kinds that other files add to (``--noise=<kind>``).

The three of the 2018 OpenAI-baselines DDPG (``baselines/ddpg/noise.py``, ``ddpg_learner.py``), which is the
paper's comparison:

* ``normal``: a = clip(mu(s) + N(0, sigma^2)).
* ``ou``: x <- x + theta (0 - x) dt + sigma sqrt(dt) N(0, 1), reset to 0 at every
  episode start; a = clip(mu(s) + x).
* ``adaptive-param`` (Plappert et al., 2018): the actor's non-LayerNorm
  parameters are perturbed with N(0, sigma^2) at every episode start; every
  ``adapt_every`` updates a separately perturbed copy is compared with the
  actor on a replay minibatch, and sigma is divided by ``adapt_coef`` if the
  action distance sqrt(mean((mu - mu~)^2)) exceeds the desired stddev, and
  multiplied by it otherwise.

and ``none`` (a = clip(mu(s)), a control).

*Action-noise kinds.* Every kind but ``adaptive-param`` (parameter noise, built into the explorer) is a
:class:`NoiseKind` in a registry: a per-seed process state (``NoiseState.process``), an optional
``episode_start`` and a ``sample`` that gives the step's noise as ``z`` and a ``scale`` (the action is
clip(mu(s) + scale * z)). A kind whose ``z`` is standard normal at every step (``policy_noise``: white or
colored) can also be the sampling noise of a stochastic student (``metapg_jax.strategies.own``). Other files
register more (``register_kind``): colored noise (``strategies/pink.py``), per-episode scales
(``strategies/mixed.py``); their fields live in config groups of their own (``strategy.register_group``).

``NoiseExplorer`` is the DDPG baseline's explorer, registered as ``ddpg`` (``--method=ddpg``; its group is
``noise``, its shortcut ``--noise``). It only chooses actions; the loop's cycle (``Trainer.acting_cycle``) is
``rollout_steps`` steps of the noisy actor, stored, then ``train_steps`` student updates (with the
stddev adaptation between blocks of ``adapt_every`` of them for adaptive parameter noise).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable

import jax
import jax.numpy as jnp
from flax import struct

from metapg_jax import strategy
from metapg_jax.config import positive
from metapg_jax.loop import Trainer
from metapg_jax.networks import is_layer_norm_path
from metapg_jax.types import Params


@dataclasses.dataclass(frozen=True)
class NoiseConfig:
    """Exploration noise of the DDPG baseline (the ``noise`` group; other explorers leave it unused)."""

    kind: str = "adaptive-param"   # 'normal', 'ou', 'adaptive-param', 'none' or a registered kind ('pink', 'mixed')
    stddev: float = 0.2            # normal/ou/pink sigma; adaptive-param: initial and desired action stddev
    ou_theta: float = 0.15         # OU mean reversion (baselines)
    ou_dt: float = 1e-2            # OU time step (baselines)
    adapt_every: int = 50          # adaptive-param: updates between stddev adaptations
    adapt_coef: float = 1.01       # adaptive-param: multiplicative adaptation factor


@struct.dataclass
class NoiseState:
    process: Any               # the action-noise kind's per-seed state (OU's x, a colored sequence, ...)
    stddev: jax.Array          # current parameter-noise stddev (adaptive-param)
    perturbed: Params          # perturbed actor parameters (adaptive-param; else unused copy)
    distance: jax.Array        # last measured action distance (adaptive-param)


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
PARAMETER_NOISE = "adaptive-param"   # built into the explorer (it perturbs parameters, not actions)


def register_kind(kind: NoiseKind) -> NoiseKind:
    """Registers an action-noise kind (a name registered again is replaced: a plug-in re-imported)."""
    if kind.name == PARAMETER_NOISE:
        raise ValueError(f"noise kind {kind.name!r} is built in")
    _KINDS[kind.name] = kind
    return kind


def kinds() -> dict[str, NoiseKind]:
    """Every registered action-noise kind (the built-in files' once imported)."""
    strategy.load_builtins()
    return dict(_KINDS)


def kind(name: str) -> NoiseKind:
    known = kinds()
    if name not in known:
        raise ValueError(f"unknown noise {name!r}; valid noises: {', '.join(names())}")
    return known[name]


def names() -> list[str]:
    """Every value ``noise.kind`` takes, sorted."""
    return sorted([*kinds(), PARAMETER_NOISE])


def _normal_sample(config, process, key):
    return jax.random.normal(key, process.shape), config.noise.stddev, process


def _ou_sample(config, x, key):
    n = config.noise
    x = x + n.ou_theta * (0.0 - x) * n.ou_dt + n.stddev * jnp.sqrt(n.ou_dt) * jax.random.normal(key, x.shape)
    return x, 1.0, x


def _zeros(config, action_size: int) -> jax.Array:
    """A zero vector of the action's shape (the process of kinds without state: it carries the shape)."""
    return jnp.zeros((action_size,), jnp.float32)


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


def perturb(params: Params, key: jax.Array, stddev: jax.Array) -> Params:
    """Adds N(0, stddev^2) to every parameter outside LayerNorm modules."""
    leaves, treedef = jax.tree_util.tree_flatten_with_path(params)
    keys = jax.random.split(key, len(leaves))
    out = [
        x if is_layer_norm_path(path) else x + stddev * jax.random.normal(k, x.shape, x.dtype)
        for (path, x), k in zip(leaves, keys)
    ]
    return jax.tree_util.tree_unflatten(treedef, out)


def init(config, actor_params: Params, action_size: int) -> NoiseState:
    n = config.noise
    process = () if n.kind == PARAMETER_NOISE else kind(n.kind).init(config, action_size)
    return NoiseState(process=process, stddev=jnp.asarray(n.stddev, jnp.float32), perturbed=actor_params,
                      distance=jnp.zeros((), jnp.float32))


def episode_start(config, state: NoiseState, actor_params: Params, key: jax.Array) -> NoiseState:
    """What baselines' ``agent.reset()`` does at the start of every episode (and a kind's new episode)."""
    if config.noise.kind == PARAMETER_NOISE:
        return state.replace(perturbed=perturb(actor_params, key, state.stddev))
    start = kind(config.noise.kind).episode_start
    return state.replace(process=start(config, state.process, key)) if start else state


def sample(config, state: NoiseState, key: jax.Array) -> tuple[jax.Array, Any, NoiseState]:
    """One step of the action-noise kind: (z, scale, the new state)."""
    z, scale, process = kind(config.noise.kind).sample(config, state.process, key)
    return z, scale, state.replace(process=process)


def act(config, state: NoiseState, actor_apply: Callable, actor_params: Params,
        obs: jax.Array, key: jax.Array) -> tuple[jax.Array, NoiseState]:
    """Noisy action in [-1, 1] for one (normalised) observation."""
    if config.noise.kind == PARAMETER_NOISE:
        return jnp.clip(actor_apply(state.perturbed, obs), -1.0, 1.0), state
    mu = actor_apply(actor_params, obs)
    z, scale, state = sample(config, state, key)
    return jnp.clip(mu + scale * z, -1.0, 1.0), state


def adapt(config, state: NoiseState, actor_apply: Callable, actor_params: Params,
          obs_batch: jax.Array, key: jax.Array) -> NoiseState:
    """Adaptive parameter noise: one stddev adaptation on a batch of normalised observations."""
    n = config.noise
    if n.kind != PARAMETER_NOISE:
        return state
    probe = perturb(actor_params, key, state.stddev)
    diff = actor_apply(actor_params, obs_batch) - actor_apply(probe, obs_batch)
    distance = jnp.sqrt(jnp.mean(jnp.square(diff)))
    stddev = jnp.where(distance > n.stddev, state.stddev / n.adapt_coef, state.stddev * n.adapt_coef)
    return state.replace(stddev=stddev, distance=distance)


@dataclasses.dataclass(frozen=True)
class NoiseExplorer:
    """The DDPG baselines' exploration: the student's actor plus noise (``config.noise``). It only acts
    (``metapg_jax.strategy.ActingExplorer``): the loop's cycle is ``rollout_steps`` noisy-actor steps, stored,
    then ``train_steps`` updates, with the stddev adaptation before every ``adapt_every`` of them for adaptive
    parameter noise (baselines' ``t_train % param_noise_adaption_interval == 0``)."""

    config: Any

    @property
    def adapt_every(self) -> int:
        n = self.config.noise
        return n.adapt_every if n.kind == PARAMETER_NOISE else 0

    def init(self, trainer: Trainer, student, key: jax.Array) -> NoiseState:
        return init(self.config, student.actor, trainer.student.action_size)

    def episode_start(self, trainer: Trainer, carry: NoiseState, student, key: jax.Array) -> NoiseState:
        return episode_start(self.config, carry, student.actor, key)

    def act(self, trainer: Trainer, carry: NoiseState, student, normalizer, obs, key: jax.Array):
        learner = trainer.student
        return act(self.config, carry, learner.actor_apply, student.actor, learner.normalize(normalizer, obs), key)

    def adapt(self, trainer: Trainer, carry: NoiseState, student, normalizer, batch, key: jax.Array) -> NoiseState:
        learner = trainer.student
        return adapt(self.config, carry, learner.actor_apply, student.actor, learner.normalize(normalizer, batch.obs),
                     key)

    def metrics(self, carry: NoiseState) -> dict:
        return {"param_noise_stddev": carry.stddev, "param_noise_distance": carry.distance,
                **kind_metrics(self.config, carry)}


def kind_metrics(config, state: NoiseState) -> dict:
    """The action-noise kind's own per-cycle metrics (none for most)."""
    if config.noise.kind == PARAMETER_NOISE:
        return {}
    own = kind(config.noise.kind).metrics
    return own(config, state.process) if own else {}


# The 2018 baselines' noises (the golden numbers' cases); ``names()`` lists every kind.
NOISES = ("normal", "ou", "adaptive-param", "none")


def _group_defaults(config) -> NoiseConfig:
    """The modern preset explores with Gaussian noise 0.1 (the paper preset: adaptive parameter noise 0.2)."""
    return NoiseConfig(kind="normal", stddev=0.1) if config.preset == "modern" else NoiseConfig()


def validate_kind(config) -> None:
    """The checks of ``config.noise`` for an explorer that uses it (``ddpg``, ``own``)."""
    n = config.noise
    if n.kind not in names():
        raise ValueError(f"unknown noise {n.kind!r}; valid noises: {', '.join(names())}")
    if n.kind != "none":
        positive("noise.stddev", n.stddev)
    positive("noise.adapt_every", n.adapt_every)
    if n.kind == PARAMETER_NOISE:
        if not (math.isfinite(n.adapt_coef) and n.adapt_coef >= 1):
            raise ValueError(f"noise.adapt_coef must be a finite number >= 1 (the stddev is multiplied or divided "
                             f"by it; 1 keeps it fixed), got {n.adapt_coef!r}")
    else:
        kind(n.kind).validate(config)


def _validate(config) -> None:
    run = config.run
    if run.method != NAME:
        return
    validate_kind(config)
    if strategy.student(config.student).stochastic:
        raise ValueError(f"--student={config.student} explores with its own stochastic policy: use --method=own "
                         f"(--noise=normal or pink: its sampling noise), not --method={NAME}")
    check_warmup(config)


def check_warmup(config) -> None:
    """An acting explorer's run must leave the warm-up of uniformly random actions before its budget ends."""
    run = config.run
    if run.warmup_steps and run.warmup_steps >= run.total_steps:
        raise ValueError(f"run.warmup_steps={run.warmup_steps} is not below the budget of {run.total_steps} "
                         f"env steps: the --method={run.method} run would act at random throughout (lower it with "
                         f"--set run.warmup_steps=N, or raise --steps)")


NAME = "ddpg"
strategy.register_explorer(
    NAME, NoiseExplorer, group=NoiseConfig, group_name="noise",
    group_defaults=_group_defaults, validate=_validate, flag=("noise", "kind"),
    label=lambda config: config.noise.kind,
    summary="the DDPG baselines' exploration: the student's actor plus noise (--noise)")
