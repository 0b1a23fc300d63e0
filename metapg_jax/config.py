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
"""

from __future__ import annotations

import dataclasses
import math
import typing
from typing import Any

import envs
from metapg_jax import strategy

PRESETS = ("paper", "modern", "tuned")
# Fields that make_config's own arguments set (with the task's protocol and budget): not overridable.
IDENTITY_FIELDS = {"preset": "preset", "env.name": "task", "run.method": "method", "student": "student"}
CORE_GROUPS = ("env", "run", "ddpg")


@dataclasses.dataclass(frozen=True)
class EnvConfig:
    name: str = "pendulum"            # task, one of envs.TASKS
    source: str = "gymnasium"         # 'gymnasium' (reference) or 'brax' (fast, simplified models)
    physics: str = "mjx"              # MuJoCo tasks' engine: 'mjx' (JAX, float32) or 'mujoco' (C, float64, host CPU)
    episode_length: int = 0           # time limit; 0 = gymnasium's for the task


@dataclasses.dataclass(frozen=True)
class DDPGConfig:
    hidden: tuple[int, ...] = (64, 64)  # hidden widths of actor and critic
    layer_norm: bool = True             # LayerNorm after each hidden Dense (baselines)
    critic_action_layer: int = 1        # hidden layer whose input gets the action (0 = critic input)
    final_init: float = 3e-3            # last layers ~ U(-final_init, final_init)
    actor_lr: float = 1e-4
    critic_lr: float = 1e-3
    critic_l2: float = 1e-2             # L2 on the critic's hidden kernels (baselines: scale * sum(w^2) / 2)
    batch_size: int = 64
    tau: float = 0.01                   # soft target update rate, after every update
    gamma: float = 0.99
    normalize_obs: bool = True          # running mean/std of observations
    obs_clip: float = 5.0               # normalised observations clipped to +-obs_clip


@dataclasses.dataclass(frozen=True)
class RunConfig:
    method: str = "ddpg"           # the explorer (--method; metapg_jax.strategy)
    total_steps: int = 0           # stored env steps per seed (D0, D1, ...; evaluations excluded)
    rollout_steps: int = 100       # an explorer's env steps per cycle, unless it schedules its own (baselines: 100)
    train_steps: int = 50          # student updates per cycle
    eval_every: int = 9000         # env steps between evaluations (= one compiled chunk)
    eval_episodes: int = 10        # deterministic evaluation episodes, in parallel
    warmup_steps: int = 0          # uniformly random actions (and no updates) before this many steps
    buffer_size: int = 0           # replay capacity; 0 = min(1e6, total_steps)
    visit_samples: int = 2000      # states kept per seed of the explorer and the student (visitation figure)


@dataclasses.dataclass(frozen=True)
class Config:
    """The core groups as fields, every registered strategy's group in ``groups`` (read as ``config.<name>``;
    ``replace(name=...)`` changes either kind)."""

    env: EnvConfig = EnvConfig()
    run: RunConfig = RunConfig()
    ddpg: DDPGConfig = DDPGConfig()
    groups: tuple[tuple[str, Any], ...] = ()   # ((name, group), ...): the strategies' groups
    preset: str = "paper"
    student: str = "ddpg"           # the learner (--student; metapg_jax.strategy)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        for key, group in object.__getattribute__(self, "groups"):
            if key == name:
                return group
        known = strategy.groups()
        if name in known:  # a group registered after this config was made: its plain defaults
            return known[name][0]()
        raise AttributeError(f"config has no group {name!r}")

    def replace(self, **changes: Any) -> Config:
        """``dataclasses.replace`` that also replaces strategy groups by name."""
        core = {k: v for k, v in changes.items() if k in _FIELDS}
        rest = {k: v for k, v in changes.items() if k not in _FIELDS}
        cfg = dataclasses.replace(self, **core) if core else self
        if rest:
            names = [k for k, _ in cfg.groups]
            unknown = [k for k in rest if k not in names and k not in strategy.groups()]
            if unknown:
                raise ValueError(f"config has no group {unknown[0]!r}")
            merged = [(k, rest.pop(k, g)) for k, g in cfg.groups] + list(rest.items())
            cfg = dataclasses.replace(cfg, groups=tuple(merged))
        return cfg

    # Derived values, computed once.
    @property
    def explorer_spec(self) -> strategy.ExplorerSpec:
        return strategy.explorer(self.run.method)

    @property
    def steps_per_cycle(self) -> int:
        per_cycle = self.explorer_spec.steps_per_cycle
        return per_cycle(self) if per_cycle is not None else self.run.rollout_steps

    @property
    def cycles_per_chunk(self) -> int:
        return self.run.eval_every // self.steps_per_cycle

    @property
    def num_chunks(self) -> int:
        return self.run.total_steps // self.run.eval_every

    @property
    def buffer_capacity(self) -> int:
        return self.run.buffer_size or min(1_000_000, self.run.total_steps)

    @property
    def episode_length(self) -> int:
        return self.env.episode_length or envs.get_spec(self.env.name).episode_length


_FIELDS = {f.name for f in dataclasses.fields(Config)}


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


def _field_types(cls) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _coerce(value: Any, typ: Any, name: str) -> Any:
    """Converts a CLI string (or a Python value) to the field's declared type."""
    origin = typing.get_origin(typ)
    if typ is bool:
        if isinstance(value, bool):
            return value
        s = str(value).lower()
        if s in ("1", "true", "yes", "on"):
            return True
        if s in ("0", "false", "no", "off"):
            return False
        raise ValueError(f"{name}: expected a boolean, got {value!r}")
    if typ in (int, float, str):
        try:
            if typ is int and isinstance(value, str):
                return int(float(value)) if float(value).is_integer() else int(value)
            return typ(value)
        except (TypeError, ValueError):
            raise ValueError(f"{name}: expected {typ.__name__}, got {value!r}") from None
    if origin is tuple:
        if isinstance(value, str):
            value = [v for v in value.replace("(", "").replace(")", "").split(",") if v.strip()]
        return tuple(_coerce(v, typing.get_args(typ)[0], name) for v in value)
    raise ValueError(f"{name}: cannot set a field of type {typ}")


def make_config(env: str = "pendulum", method: str = "ddpg", preset: str = "paper", steps: int | None = None,
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


def current_name(dotted: str) -> str:
    """The current name of a dotted field (a field that moved out of a strategy's group keeps its old name)."""
    return strategy.moved_fields().get(dotted, dotted)


def override(cfg: Config, overrides: dict[str, Any]) -> Config:
    """Returns ``cfg`` with dotted fields replaced, e.g. ``{'ddpg.tau': '0.005'}``."""
    groups = {*CORE_GROUPS, *(k for k, _ in cfg.groups), *strategy.groups()}
    for dotted, value in overrides.items():
        dotted = current_name(dotted)
        parts = dotted.split(".")
        if len(parts) == 1 and parts[0] in ("preset", "student"):
            cfg = dataclasses.replace(cfg, **{parts[0]: _coerce(value, str, dotted)})
            continue
        if len(parts) != 2 or parts[0] not in groups:
            raise ValueError(f"unknown config field {dotted!r}; groups: {', '.join(sorted(groups))}")
        group = getattr(cfg, parts[0])
        types = _field_types(type(group))
        if parts[1] not in types:
            raise ValueError(f"unknown config field {dotted!r}; fields of {parts[0]}: {', '.join(types)}")
        group = dataclasses.replace(group, **{parts[1]: _coerce(value, types[parts[1]], dotted)})
        cfg = cfg.replace(**{parts[0]: group})
    return cfg


def positive(name: str, value: float) -> None:
    """A one-line ``ValueError`` unless ``value`` is a positive finite number (the checks of every group)."""
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")


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
    for spec in [*strategy.students().values(), *strategy.explorers().values()]:
        spec.validate(cfg)
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


def to_dict(cfg: Config) -> dict[str, Any]:
    """The config as plain JSON-able nested dicts (tuples become lists): the core groups, every strategy group
    by name, ``preset`` and ``student``."""
    d = {"env": cfg.env, "run": cfg.run, "ddpg": cfg.ddpg, **dict(cfg.groups)}
    out = {k: dataclasses.asdict(v) for k, v in d.items()}
    return json_roundtrip({**out, "preset": cfg.preset, "student": cfg.student})


def json_roundtrip(obj: Any) -> Any:
    import json

    return json.loads(json.dumps(obj))


def from_dict(d: dict[str, Any]) -> Config:
    """Inverse of ``to_dict`` (used to resume a run from its stored config). A stored field that has since
    moved (``strategy.moved_fields``) is read into its new place; a group stored without one of today's
    fields gets the field's default."""
    known = strategy.groups()
    core = {"env": EnvConfig, "run": RunConfig, "ddpg": DDPGConfig}
    values: dict[str, dict] = {k: dict(v) for k, v in d.items() if isinstance(v, dict)}
    for old, new in strategy.moved_fields().items():
        group, field = old.split(".")
        if field in values.get(group, {}):
            value = values[group].pop(field)
            g2, f2 = new.split(".")
            values.setdefault(g2, {}).setdefault(f2, value)
    unknown = [k for k in values if k not in core and k not in known]
    if unknown:
        raise ValueError(f"stored config has a group {unknown[0]!r} that no registered strategy declares "
                         f"(load its plug-in first: --plugin)")

    def build(name: str, cls: type) -> Any:
        types = _field_types(cls)
        stray = set(values[name]) - set(types)
        if stray:
            raise ValueError(f"stored config has unknown fields {sorted(stray)} in group {name!r}")
        return cls(**{k: _coerce(v, types[k], f"{name}.{k}") for k, v in values[name].items()})

    fields = {name: build(name, cls) for name, cls in core.items() if name in values}
    groups = tuple((name, build(name, cls) if name in values else cls()) for name, (cls, _) in known.items())
    top = {k: d[k] for k in ("preset", "student") if k in d}
    return Config(**fields, groups=groups, **top)


def diff(a: dict[str, Any], b: dict[str, Any], prefix: str = "") -> list[str]:
    """Dotted names of the fields whose values differ between two ``to_dict`` results."""
    out = []
    for k in sorted(set(a) | set(b)):
        name = f"{prefix}{k}"
        va, vb = a.get(k), b.get(k)
        if isinstance(va, dict) and isinstance(vb, dict):
            out.extend(diff(va, vb, name + "."))
        elif va != vb:
            out.append(f"{name} ({va!r} -> {vb!r})")
    return out
