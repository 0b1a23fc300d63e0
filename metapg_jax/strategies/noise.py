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

The action noises are kinds of ``metapg_jax.action_noise`` (``normal``, ``ou``, ``none`` there; colored noise
and per-episode scales in ``pink.py`` and ``mixed.py``): the explorer acts with clip(mu(s) + scale * z) for the
kind's ``z`` and ``scale``, the kind's state in ``NoiseState.process``. Adaptive parameter noise is built in
here (``metapg_jax.action_noise`` says why it is not a kind).

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

from metapg_jax import action_noise, strategy
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


PARAMETER_NOISE = action_noise.PARAMETER_NOISE   # built in here, not a kind (action_noise's docstring)


def perturb(params: Params, key: jax.Array, stddev: jax.Array) -> Params:
    """Adds N(0, stddev^2) to every parameter outside LayerNorm modules."""
    leaves, treedef = jax.tree_util.tree_flatten_with_path(params)
    keys = jax.random.split(key, len(leaves))
    out = [
        x if is_layer_norm_path(path) else x + stddev * jax.random.normal(k, x.shape, x.dtype)
        for (path, x), k in zip(leaves, keys)
    ]
    return jax.tree_util.tree_unflatten(treedef, out)


def names() -> list[str]:
    """Every value ``noise.kind`` takes with this explorer, sorted."""
    return sorted([*action_noise.kinds(), PARAMETER_NOISE])


def init(config, actor_params: Params, action_size: int) -> NoiseState:
    n = config.noise
    process = () if n.kind == PARAMETER_NOISE else action_noise.init(config, action_size)
    return NoiseState(process=process, stddev=jnp.asarray(n.stddev, jnp.float32), perturbed=actor_params,
                      distance=jnp.zeros((), jnp.float32))


def episode_start(config, state: NoiseState, actor_params: Params, key: jax.Array) -> NoiseState:
    """What baselines' ``agent.reset()`` does at the start of every episode (and a kind's new episode)."""
    if config.noise.kind == PARAMETER_NOISE:
        return state.replace(perturbed=perturb(actor_params, key, state.stddev))
    return state.replace(process=action_noise.episode_start(config, state.process, key))


def act(config, state: NoiseState, actor_apply: Callable, actor_params: Params,
        obs: jax.Array, key: jax.Array) -> tuple[jax.Array, NoiseState]:
    """Noisy action in [-1, 1] for one (normalised) observation."""
    if config.noise.kind == PARAMETER_NOISE:
        return jnp.clip(actor_apply(state.perturbed, obs), -1.0, 1.0), state
    mu = actor_apply(actor_params, obs)
    z, scale, process = action_noise.sample(config, state.process, key)
    return jnp.clip(mu + scale * z, -1.0, 1.0), state.replace(process=process)


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
class NoiseExplorer(strategy.ActingExplorer):
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
        own = {} if self.config.noise.kind == PARAMETER_NOISE else action_noise.metrics(self.config, carry.process)
        return {"param_noise_stddev": carry.stddev, "param_noise_distance": carry.distance, **own}


def _group_defaults(config) -> NoiseConfig:
    """The modern preset explores with Gaussian noise 0.1 (the paper preset: adaptive parameter noise 0.2)."""
    return NoiseConfig(kind="normal", stddev=0.1) if config.preset == "modern" else NoiseConfig()


def _validate(config) -> None:
    n = config.noise
    if config.run.method != NAME:
        return
    if n.kind not in names():
        raise ValueError(f"unknown noise {n.kind!r}; valid noises: {', '.join(names())}")
    if strategy.student(config.student).stochastic:
        raise ValueError(f"--student={config.student} explores with its own stochastic policy: use --method=own "
                         f"(--noise=normal or pink: its sampling noise), not --method={NAME}")
    positive("noise.adapt_every", n.adapt_every)
    if n.kind == PARAMETER_NOISE:
        positive("noise.stddev", n.stddev)
        if not (math.isfinite(n.adapt_coef) and n.adapt_coef >= 1):
            raise ValueError(f"noise.adapt_coef must be a finite number >= 1 (the stddev is multiplied or divided "
                             f"by it; 1 keeps it fixed), got {n.adapt_coef!r}")
    else:
        action_noise.validate(config)
    action_noise.check_warmup(config)


NAME = "ddpg"
strategy.register_explorer(
    NAME, NoiseExplorer, group=NoiseConfig, group_name="noise",
    group_defaults=_group_defaults, validate=_validate, flag=("noise", "kind"),
    label=lambda config: config.noise.kind,
    summary="the DDPG baselines' exploration: the student's actor plus noise (--noise)")
