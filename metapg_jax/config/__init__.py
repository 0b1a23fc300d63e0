"""Typed, frozen configuration grouped by concern, plus the presets.

``make_config(env, method, preset, ...)`` builds a complete config from a task's protocol (``envs.TASKS``),
a preset and the chosen student and explorer; ``override(config, {'ddpg.actor_lr': 3e-4})`` changes fields by
dotted name with type checking; ``validate(config)`` raises a one-line ``ValueError`` for anything that would
fail or silently misbehave, before anything is compiled.

The groups: ``env``, ``run`` and ``ddpg`` (the actor-critic settings every student shares: networks,
optimisers, batch, tau, gamma, observation normalisation) are the core's; every registered strategy
(``metapg_jax.strategy``) adds its own group (``config.<name>``), with its defaults per task and preset,
its schedule and its checks, all declared in the strategy's file. This module imports no strategy and
branches on none (the defaults, ``method='ddpg'`` and ``student='ddpg'``, are names).

Presets (the core's part; each strategy adds its own):
* ``paper``: the 2018 OpenAI-baselines DDPG the paper builds on (64-64 + LayerNorm, action at the
  critic's second layer, Adam 1e-4 / 1e-3, batch 64, tau 0.01, critic L2 1e-2, cycles of 100 rollout
  steps and 50 updates).
* ``modern``: a 2020s actor-critic (256-256 without LayerNorm, action at the critic's input, Adam 3e-4
  both, batch 256, tau 0.005, no critic L2, no observation normalisation, one update per env step,
  5000 uniformly random warm-up steps).
* ``tuned``: the paper preset, with the changes the strategies declare for it (the teacher's schedule
  from the screen of teacher variants; ``metapg_jax.strategies.meta``).

Deviations from the paper that live here (docs/algorithm.md, "Deviations from the paper"): the noise
baseline's 100 rollout steps per cycle (the paper's Table 1: 200).

The package by concern: ``schema`` (the types and ``Config``), ``build`` (``make_config``, ``validate``),
``fields`` (overrides by dotted name, (de)serialisation); its public names are imported here.
"""

from metapg_jax.config.build import default_eval_every, make_config, validate
from metapg_jax.config.fields import current_name, diff, from_dict, json_roundtrip, override, to_dict
from metapg_jax.config.schema import (CORE_GROUPS, IDENTITY_FIELDS, PRESETS, Config, DDPGConfig, EnvConfig,
                                      RunConfig, positive)

__all__ = ["CORE_GROUPS", "IDENTITY_FIELDS", "PRESETS", "Config", "DDPGConfig", "EnvConfig", "RunConfig",
           "current_name", "default_eval_every", "diff", "from_dict", "json_roundtrip", "make_config", "override",
           "positive", "to_dict", "validate"]
