"""Exploration noise of the DDPG baseline: Gaussian, Ornstein-Uhlenbeck, adaptive parameter noise.

All three as in the 2018 OpenAI-baselines DDPG (``baselines/ddpg/noise.py``,
``ddpg_learner.py``), which is the paper's comparison:

* ``normal``: a = clip(mu(s) + N(0, sigma^2)).
* ``ou``: x <- x + theta (0 - x) dt + sigma sqrt(dt) N(0, 1), reset to 0 at every
  episode start; a = clip(mu(s) + x).
* ``adaptive-param`` (Plappert et al., 2018): the actor's non-LayerNorm
  parameters are perturbed with N(0, sigma^2) at every episode start; every
  ``adapt_every`` updates a separately perturbed copy is compared with the
  actor on a replay minibatch, and sigma is divided by ``adapt_coef`` if the
  action distance sqrt(mean((mu - mu~)^2)) exceeds the desired stddev, and
  multiplied by it otherwise.

``NoiseExplorer`` is the DDPG baseline's explorer, registered as ``ddpg`` (``--method=ddpg``; its group is
``noise``, its shortcut ``--noise``). It only chooses actions; the loop's cycle (``Trainer.acting_cycle``) is
``rollout_steps`` steps of the noisy actor, stored, then ``train_steps`` student updates (with the
stddev adaptation between blocks of ``adapt_every`` of them for adaptive parameter noise).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable

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

    kind: str = "adaptive-param"   # 'normal', 'ou', 'adaptive-param' or 'none'
    stddev: float = 0.2            # normal/ou sigma; adaptive-param: initial and desired action stddev
    ou_theta: float = 0.15         # OU mean reversion (baselines)
    ou_dt: float = 1e-2            # OU time step (baselines)
    adapt_every: int = 50          # adaptive-param: updates between stddev adaptations
    adapt_coef: float = 1.01       # adaptive-param: multiplicative adaptation factor


@struct.dataclass
class NoiseState:
    ou: jax.Array              # (action_size,) OU process value
    stddev: jax.Array          # current parameter-noise stddev (adaptive-param)
    perturbed: Params          # perturbed actor parameters (adaptive-param; else unused copy)
    distance: jax.Array        # last measured action distance (adaptive-param)


def perturb(params: Params, key: jax.Array, stddev: jax.Array) -> Params:
    """Adds N(0, stddev^2) to every parameter outside LayerNorm modules."""
    leaves, treedef = jax.tree_util.tree_flatten_with_path(params)
    keys = jax.random.split(key, len(leaves))
    out = [
        x if is_layer_norm_path(path) else x + stddev * jax.random.normal(k, x.shape, x.dtype)
        for (path, x), k in zip(leaves, keys)
    ]
    return jax.tree_util.tree_unflatten(treedef, out)


def init(cfg: NoiseConfig, actor_params: Params, action_size: int) -> NoiseState:
    return NoiseState(
        ou=jnp.zeros((action_size,), jnp.float32),
        stddev=jnp.asarray(cfg.stddev, jnp.float32),
        perturbed=actor_params,
        distance=jnp.zeros((), jnp.float32),
    )


def episode_start(cfg: NoiseConfig, state: NoiseState, actor_params: Params, key: jax.Array) -> NoiseState:
    """What baselines' ``agent.reset()`` does at the start of every episode."""
    if cfg.kind == "ou":
        return state.replace(ou=jnp.zeros_like(state.ou))
    if cfg.kind == "adaptive-param":
        return state.replace(perturbed=perturb(actor_params, key, state.stddev))
    return state


def act(cfg: NoiseConfig, state: NoiseState, actor_apply: Callable, actor_params: Params,
        obs: jax.Array, key: jax.Array) -> tuple[jax.Array, NoiseState]:
    """Noisy action in [-1, 1] for one (normalised) observation."""
    if cfg.kind == "adaptive-param":
        return jnp.clip(actor_apply(state.perturbed, obs), -1.0, 1.0), state
    mu = actor_apply(actor_params, obs)
    if cfg.kind == "normal":
        return jnp.clip(mu + cfg.stddev * jax.random.normal(key, mu.shape), -1.0, 1.0), state
    if cfg.kind == "ou":
        x = state.ou + cfg.ou_theta * (0.0 - state.ou) * cfg.ou_dt + cfg.stddev * jnp.sqrt(
            cfg.ou_dt) * jax.random.normal(key, mu.shape)
        return jnp.clip(mu + x, -1.0, 1.0), state.replace(ou=x)
    return jnp.clip(mu, -1.0, 1.0), state


def adapt(cfg: NoiseConfig, state: NoiseState, actor_apply: Callable, actor_params: Params,
          obs_batch: jax.Array, key: jax.Array) -> NoiseState:
    """Adaptive parameter noise: one stddev adaptation on a batch of normalised observations."""
    if cfg.kind != "adaptive-param":
        return state
    probe = perturb(actor_params, key, state.stddev)
    diff = actor_apply(actor_params, obs_batch) - actor_apply(probe, obs_batch)
    distance = jnp.sqrt(jnp.mean(jnp.square(diff)))
    stddev = jnp.where(distance > cfg.stddev, state.stddev / cfg.adapt_coef, state.stddev * cfg.adapt_coef)
    return state.replace(stddev=stddev, distance=distance)


@dataclasses.dataclass(frozen=True)
class NoiseExplorer:
    """The DDPG baselines' exploration: the student's actor plus noise (``config.noise``). It only acts
    (``metapg_jax.strategy.ActingExplorer``): the loop's cycle is ``rollout_steps`` noisy-actor steps, stored,
    then ``train_steps`` updates, with the stddev adaptation before every ``adapt_every`` of them for adaptive
    parameter noise (baselines' ``t_train % param_noise_adaption_interval == 0``)."""

    cfg: NoiseConfig

    @property
    def adapt_every(self) -> int:
        return self.cfg.adapt_every if self.cfg.kind == "adaptive-param" else 0

    def init(self, trainer: Trainer, student, key: jax.Array) -> NoiseState:
        return init(self.cfg, student.actor, trainer.student.action_size)

    def episode_start(self, trainer: Trainer, carry: NoiseState, student, key: jax.Array) -> NoiseState:
        return episode_start(self.cfg, carry, student.actor, key)

    def act(self, trainer: Trainer, carry: NoiseState, student, normalizer, obs, key: jax.Array):
        learner = trainer.student
        return act(self.cfg, carry, learner.actor_apply, student.actor, learner.normalize(normalizer, obs), key)

    def adapt(self, trainer: Trainer, carry: NoiseState, student, normalizer, batch, key: jax.Array) -> NoiseState:
        learner = trainer.student
        return adapt(self.cfg, carry, learner.actor_apply, student.actor, learner.normalize(normalizer, batch.obs), key)

    def metrics(self, carry: NoiseState) -> dict:
        return {"param_noise_stddev": carry.stddev, "param_noise_distance": carry.distance}


NOISES = ("normal", "ou", "adaptive-param", "none")


def _group_defaults(config) -> NoiseConfig:
    """The modern preset explores with Gaussian noise 0.1 (the paper preset: adaptive parameter noise 0.2)."""
    return NoiseConfig(kind="normal", stddev=0.1) if config.preset == "modern" else NoiseConfig()


def _validate(config) -> None:
    n = config.noise
    if n.kind not in NOISES:
        raise ValueError(f"unknown noise {n.kind!r}; valid noises: {', '.join(NOISES)}")
    if n.kind != "none":
        positive("noise.stddev", n.stddev)
    positive("noise.adapt_every", n.adapt_every)
    if n.kind == "ou":
        positive("noise.ou_dt", n.ou_dt)
        if not (math.isfinite(n.ou_theta) and n.ou_theta >= 0):
            raise ValueError(f"noise.ou_theta must be a finite number >= 0, got {n.ou_theta!r}")
    if n.kind == "adaptive-param" and not (math.isfinite(n.adapt_coef) and n.adapt_coef >= 1):
        raise ValueError(f"noise.adapt_coef must be a finite number >= 1 (the stddev is multiplied or divided by "
                         f"it; 1 keeps it fixed), got {n.adapt_coef!r}")
    run = config.run
    if run.method == NAME and run.warmup_steps and run.warmup_steps >= run.total_steps:
        raise ValueError(f"run.warmup_steps={run.warmup_steps} is not below the budget of {run.total_steps} "
                         f"env steps: the DDPG run would act at random throughout (lower it with "
                         f"--set run.warmup_steps=N, or raise --steps)")


NAME = "ddpg"
strategy.register_explorer(
    NAME, lambda config: NoiseExplorer(config.noise), group=NoiseConfig, group_name="noise",
    group_defaults=_group_defaults, validate=_validate, flag=("noise", "kind"),
    label=lambda config: config.noise.kind,
    summary="the DDPG baselines' exploration: the student's actor plus noise (--noise)")
