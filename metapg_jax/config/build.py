"""A complete config from a task, a preset, a student and an explorer (``make_config``), the evaluation interval
it derives from the budget, and the checks run before anything compiles (``validate``)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import envs
from metapg_jax import strategy
from metapg_jax.config.fields import current_name, override
from metapg_jax.config.schema import (IDENTITY_FIELDS, PRESETS, Config, DDPGConfig, EnvConfig, RunConfig,
                                      positive)

def default_eval_every(total_steps: int, cycle: int, target: int) -> int:
    """The multiple of ``cycle`` dividing ``total_steps`` closest to ``target``.

    With the task defaults this is the task's ``eval_every`` (a multiple of both
    methods' cycles, so DDPG and Meta are evaluated at the same sample counts).
    Returns ``target`` unchanged when ``total_steps`` is not a whole number of
    cycles, so that ``validate`` names the real problem.
    """
    if cycle <= 0 or total_steps <= 0 or total_steps % cycle:
        return target
    n = total_steps // cycle
    best = n
    d = 1
    while d * d <= n:
        if n % d == 0:
            for k in (d, n // d):
                if abs(k * cycle - target) < abs(best * cycle - target):
                    best = k
        d += 1
    return best * cycle


def make_config(env: str = envs.DEFAULT_TASK, method: str = "ddpg", preset: str = "paper", steps: int | None = None,
                source: str = "gymnasium", overrides: dict[str, Any] | None = None, physics: str = "mjx",
                student: str = "ddpg", **flags: Any) -> Config:
    """A full config from a task, a method (explorer) and a preset (see the module docstring).

    ``physics='auto'`` is resolved here (``envs.resolve_physics``), so a config always names the engine it runs
    on. ``flags`` are the explorers' command-line shortcuts (``strategy.flags()``: ``noise='ou'``,
    ``teacher='variance'``), applied before ``overrides``; None leaves the field as it is.

    Order: the core's preset; every registered group's defaults for the task and preset; the student's, then
    the explorer's schedule; the shortcuts and ``overrides``; the student's and the explorer's derived fields;
    the evaluation interval."""
    spec = envs.get_spec(env)
    physics = envs.resolve_physics(env, source, physics)
    if preset not in PRESETS:
        raise ValueError(f"unknown preset {preset!r}; valid presets: {', '.join(PRESETS)}")
    explorer, learner = strategy.explorer(method), strategy.student(student)
    shortcuts = strategy.flags()
    unknown = [k for k in flags if k not in shortcuts]
    if unknown:
        raise TypeError(f"make_config() got an unexpected keyword argument {unknown[0]!r}")
    total = envs.default_budget(env) if steps is None else steps
    run = RunConfig(method=method, total_steps=total)
    ddpg = DDPGConfig()
    if preset == "modern":
        ddpg = DDPGConfig(hidden=(256, 256), layer_norm=False, critic_action_layer=0,
                          actor_lr=3e-4, critic_lr=3e-4, critic_l2=0.0, batch_size=256, tau=0.005,
                          normalize_obs=False)
        run = dataclasses.replace(run, rollout_steps=1, train_steps=1, warmup_steps=5000)
    cfg = Config(env=EnvConfig(env, source, physics=physics), run=run, ddpg=ddpg, preset=preset, student=student)
    cfg = cfg.replace(groups=tuple((name, defaults(cfg) if defaults else cls())
                                   for name, (cls, defaults) in strategy.groups().items()))
    cfg = explorer.schedule(learner.schedule(cfg))
    overrides = dict(overrides or {})
    named = [k for k in overrides if k in IDENTITY_FIELDS]
    if named:
        # These name the run (folder, label, the task's protocol and budget) and are read before overrides.
        raise ValueError(f"{named[0]} cannot be overridden with --set; choose it with the command's "
                         f"{IDENTITY_FIELDS[named[0]]} option")
    given = {shortcuts[k][1]: v for k, v in flags.items() if v is not None}
    if given:
        cfg = override(cfg, given)
    if overrides:
        cfg = override(cfg, overrides)
    overrides = {current_name(k): v for k, v in overrides.items()}
    cfg = explorer.derive(learner.derive(cfg, overrides), overrides)
    if "run.eval_every" not in overrides:
        target = min(spec.eval_every, max(cfg.steps_per_cycle, cfg.run.total_steps // 10))
        every = default_eval_every(cfg.run.total_steps, cfg.steps_per_cycle, target)
        cfg = dataclasses.replace(cfg, run=dataclasses.replace(cfg.run, eval_every=every))
    return cfg


def validate(cfg: Config) -> Config:
    """Raises ``ValueError`` with one clear line for a config that cannot run as asked: the core's checks, then
    every registered strategy's own (``metapg_jax.strategy``)."""
    envs.get_spec(cfg.env.name)
    if cfg.env.source not in envs.SOURCES:
        raise ValueError(f"unknown source {cfg.env.source!r}; valid sources: {', '.join(envs.SOURCES)}")
    envs.check_physics(cfg.env.name, cfg.env.source, cfg.env.physics)
    explorer = strategy.explorer(cfg.run.method)
    strategy.student(cfg.student)
    if cfg.preset not in PRESETS:
        raise ValueError(f"unknown preset {cfg.preset!r}; valid presets: {', '.join(PRESETS)}")
    if cfg.env.episode_length < 0:
        raise ValueError(f"env.episode_length must be >= 0 (0 = the task's), got {cfg.env.episode_length}")
    for name in ("total_steps", "rollout_steps", "train_steps", "eval_every", "eval_episodes", "visit_samples"):
        positive(f"run.{name}", getattr(cfg.run, name))
    if cfg.run.warmup_steps < 0 or cfg.run.buffer_size < 0:
        raise ValueError("run.warmup_steps and run.buffer_size must be >= 0")
    for name in ("actor_lr", "critic_lr", "batch_size", "tau", "gamma", "obs_clip"):
        positive(f"ddpg.{name}", getattr(cfg.ddpg, name))
    if not cfg.ddpg.hidden or min(cfg.ddpg.hidden) <= 0:
        raise ValueError(f"ddpg.hidden must be a non-empty tuple of positive widths, got {cfg.ddpg.hidden}")
    if not 0 <= cfg.ddpg.critic_action_layer < len(cfg.ddpg.hidden):
        raise ValueError(f"ddpg.critic_action_layer must be in [0, {len(cfg.ddpg.hidden)}), got {cfg.ddpg.critic_action_layer}")
    if cfg.ddpg.tau > 1 or cfg.ddpg.gamma > 1:
        raise ValueError("ddpg.tau and ddpg.gamma must be <= 1")
    if cfg.ddpg.critic_l2 < 0 or not math.isfinite(cfg.ddpg.critic_l2):
        raise ValueError(f"ddpg.critic_l2 must be >= 0, got {cfg.ddpg.critic_l2}")
    if not (math.isfinite(cfg.ddpg.final_init) and cfg.ddpg.final_init >= 0):
        raise ValueError(f"ddpg.final_init must be a finite number >= 0, got {cfg.ddpg.final_init!r}")
    for check in strategy.validators():
        check(cfg)
    cycle = cfg.steps_per_cycle
    if cfg.run.total_steps % cycle:
        raise ValueError(f"run.total_steps={cfg.run.total_steps} is not a multiple of the {cycle} env steps "
                         f"one {explorer.name} cycle stores")
    if cfg.run.eval_every % cycle:
        raise ValueError(f"run.eval_every={cfg.run.eval_every} is not a multiple of the {cycle} env steps "
                         f"one {explorer.name} cycle stores")
    if cfg.run.total_steps % cfg.run.eval_every:
        raise ValueError(f"run.total_steps={cfg.run.total_steps} is not a multiple of run.eval_every="
                         f"{cfg.run.eval_every} (each evaluation ends one compiled chunk); "
                         f"e.g. use --steps={max(1, cfg.run.total_steps // cfg.run.eval_every) * cfg.run.eval_every}")
    if cfg.buffer_capacity < cycle:
        raise ValueError(f"replay capacity {cfg.buffer_capacity} is smaller than one cycle ({cycle} steps)")
    if cfg.ddpg.batch_size > cfg.buffer_capacity:
        raise ValueError(f"ddpg.batch_size={cfg.ddpg.batch_size} is larger than the replay capacity "
                         f"{cfg.buffer_capacity}: no update could ever run")
    return cfg
