"""Typed, frozen configuration grouped by concern, plus the presets.

``make_config(env, method, preset, ...)`` builds a complete config from a task's
protocol (``envs.TASKS``) and a preset; ``override(config, {'ddpg.actor_lr': 3e-4})``
changes fields by dotted name with type checking; ``validate(config)`` raises a
one-line ``ValueError`` for anything that would fail or silently misbehave,
before anything is compiled.

Presets:
* ``paper``: the 2018 OpenAI-baselines DDPG the paper builds on (64-64 +
  LayerNorm, action at the critic's second layer, Adam 1e-4 / 1e-3, batch 64,
  tau 0.01, critic L2 1e-2, cycles of 100 rollout steps and 50 updates,
  adaptive parameter noise 0.2) and the paper's meta schedule per task.
* ``modern``: a 2020s DDPG (256-256 without LayerNorm, action at the critic's
  input, Adam 3e-4 both, batch 256, tau 0.005, no critic L2, no observation
  normalisation, one update per env step, Gaussian noise 0.1, 5000 uniformly
  random warm-up steps). Meta under it: the paper's schedule per task with a
  256-256 teacher without LayerNorm, one student update per stored step and
  one look-ahead update per D0 step, no warm-up.
* ``tuned``: the paper preset with the Meta schedule that the screen of teacher variants
  (``experiments.screen``, results/screen/README.md) found to help (``TUNED_META``): the
  student gets DDPG's update-to-data ratio (half a cycle's stored steps as updates; the
  look-ahead keeps the task's paper update count) and the teacher takes one REINFORCE step
  per cycle (the paper's HalfCheetah and InvertedPendulum schedule: 100). The DDPG baselines
  are the paper preset's, unchanged.

``student='td3'`` (``--student=td3``) trains TD3 instead of DDPG with the preset's networks and
optimisers; under ``modern`` its baselines keep the TD3 authors' 25k random warm-up steps.

Deviations from the paper that live here (docs/algorithm.md, "Deviations from the paper"):
DDPG's 100 rollout steps per cycle (the paper's Table 1: 200), the variance
teacher's state-dependent log-std by default, the look-ahead's update count.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from typing import Any

import envs

STUDENTS = ("ddpg", "td3")  # the built-in students; metapg_jax.students.register adds more
METHODS = ("ddpg", "meta")  # the built-in explorers; metapg_jax.explorers.register adds more
PRESETS = ("paper", "modern", "tuned")
NOISES = ("normal", "ou", "adaptive-param", "none")
TEACHERS = ("independent", "variance")
STUDENT_FROM = ("pi", "lookahead")
BASELINES = ("lookahead", "fresh")
# Fields that make_config's own arguments set (with the task's protocol and budget): not overridable.
IDENTITY_FIELDS = {"preset": "preset", "env.name": "task", "run.method": "method", "student": "student"}
_REGISTERED_METHODS: set[str] = set()  # names given to metapg_jax.explorers.register
_REGISTERED_STUDENTS: set[str] = set()  # names given to metapg_jax.students.register


def register_method(name: str) -> None:
    """Lets ``validate`` accept ``run.method == name`` (called by ``metapg_jax.explorers.register``).
    A registered method's cycle stores ``run.rollout_steps`` steps, like the DDPG baseline's."""
    _REGISTERED_METHODS.add(name)


def register_student(name: str) -> None:
    """Lets ``make_config`` and ``validate`` accept ``student == name`` (called by
    ``metapg_jax.students.register``)."""
    _REGISTERED_STUDENTS.add(name)


def _check_student(student: str) -> None:
    if student not in STUDENTS and student not in _REGISTERED_STUDENTS:
        valid = ", ".join([*STUDENTS, *sorted(_REGISTERED_STUDENTS - set(STUDENTS))])
        raise ValueError(f"unknown student {student!r}; valid students: {valid}")


def _check_method(method: str) -> None:
    if method not in METHODS and method not in _REGISTERED_METHODS:
        valid = ", ".join([*METHODS, *sorted(_REGISTERED_METHODS - set(METHODS))])
        raise ValueError(f"unknown method {method!r}; valid methods: {valid}")


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
class TD3Config:
    """TD3's own settings (Fujimoto et al., 2018; in normalised action units); the networks, optimisers,
    batch, tau and gamma are the ``ddpg`` group's."""

    policy_noise: float = 0.2      # target-policy smoothing noise stddev
    noise_clip: float = 0.5        # ... clipped to +-noise_clip
    policy_delay: int = 2          # actor and target updates every policy_delay critic updates


@dataclasses.dataclass(frozen=True)
class NoiseConfig:
    """Exploration noise of the DDPG baseline (unused by ``meta``: the teacher explores)."""

    kind: str = "adaptive-param"   # 'normal', 'ou', 'adaptive-param' or 'none'
    stddev: float = 0.2            # normal/ou sigma; adaptive-param: initial and desired action stddev
    ou_theta: float = 0.15         # OU mean reversion (baselines)
    ou_dt: float = 1e-2            # OU time step (baselines)
    adapt_every: int = 50          # adaptive-param: updates between stddev adaptations
    adapt_coef: float = 1.01       # adaptive-param: multiplicative adaptation factor


@dataclasses.dataclass(frozen=True)
class MetaConfig:
    """The teacher and Algorithm 1's schedule (../shared/DESIGN.md, paper section 4 and 5.1)."""

    teacher: str = "independent"    # 'independent' (own mean + log-std MLPs) or 'variance' (student mean)
    hidden: tuple[int, ...] = (64, 64)
    layer_norm: bool = True         # the paper uses LayerNorm in its policy networks
    # Variance teacher: log-std MLP (True, our default, like the log-std network of the paper's
    # section 5.1) or one learned vector (False, the paper's design (i), sigma^2 I).
    state_dependent_std: bool = True
    init_log_std: float = -0.5      # initial log-std of the teacher (ours; the paper does not say)
    min_log_std: float = -5.0       # log-std bounds (ours)
    max_log_std: float = 1.0
    lr: float = 1e-4                # teacher Adam learning rate (paper); 0 = frozen at its init (a control)
    explore_steps: int = 100        # |D0| per cycle
    eval_steps: int = 200           # |D1| per cycle, per eval env
    teacher_steps: int = 1          # REINFORCE Adam steps per cycle
    # DDPG updates of the look-ahead copy on D0; 0 = run.train_steps (50; 500 on IP/HalfCheetah).
    # The paper says "one or a small number of steps" without a number; ours is a reading.
    lookahead_steps: int = 0
    eval_envs: int = 1              # parallel envs for D1
    student_from: str = "pi"        # student update starts from pi (paper) or pi'
    baseline: str = "lookahead"     # R_hat(pi) for the next cycle: R_hat(pi') or a fresh rollout
    normalize_meta_reward: bool = False  # running mean/std of the meta reward (our addition)
    visit_samples: int = 2000       # states of teacher/student kept per seed for the visitation figure


@dataclasses.dataclass(frozen=True)
class RunConfig:
    method: str = "ddpg"           # 'ddpg' (baseline) or 'meta' (Algorithm 1)
    total_steps: int = 0           # stored env steps per seed (D0, D1, ...; evaluations excluded)
    rollout_steps: int = 100       # DDPG: noisy-actor env steps per cycle (baselines; paper's Table 1: 200)
    train_steps: int = 50          # DDPG updates per cycle (student; and the look-ahead for meta)
    eval_every: int = 9000         # env steps between evaluations (= one compiled chunk)
    eval_episodes: int = 10        # deterministic evaluation episodes, in parallel
    warmup_steps: int = 0          # uniformly random actions (and no updates) before this many steps
    buffer_size: int = 0           # replay capacity; 0 = min(1e6, total_steps)


@dataclasses.dataclass(frozen=True)
class Config:
    env: EnvConfig = EnvConfig()
    run: RunConfig = RunConfig()
    ddpg: DDPGConfig = DDPGConfig()
    noise: NoiseConfig = NoiseConfig()
    meta: MetaConfig = MetaConfig()
    td3: TD3Config = TD3Config()
    preset: str = "paper"
    student: str = "ddpg"           # the learner: 'ddpg' or 'td3'

    # Derived values, computed once.
    @property
    def steps_per_cycle(self) -> int:
        if self.run.method != "meta":  # the baseline's cycle (and a registered explorer's)
            return self.run.rollout_steps
        m = self.meta
        fresh = m.eval_steps * m.eval_envs if m.baseline == "fresh" else 0
        return m.explore_steps + m.eval_steps * m.eval_envs + fresh

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


def make_config(env: str = "pendulum", method: str = "ddpg", preset: str = "paper",
                noise: str | None = None, steps: int | None = None, source: str = "gymnasium",
                teacher: str | None = None, overrides: dict[str, Any] | None = None,
                physics: str = "mjx", student: str = "ddpg") -> Config:
    """A full config from a task, a method and a preset (see the module docstring); ``physics='auto'``
    is resolved here (``envs.resolve_physics``), so a config always names the engine it runs on."""
    spec = envs.get_spec(env)
    physics = envs.resolve_physics(env, source, physics)
    if preset not in PRESETS:
        raise ValueError(f"unknown preset {preset!r}; valid presets: {', '.join(PRESETS)}")
    _check_method(method)
    _check_student(student)
    meta = MetaConfig(explore_steps=spec.explore_steps, eval_steps=spec.eval_steps,
                      teacher_steps=spec.teacher_steps)
    if teacher is not None:
        meta = dataclasses.replace(meta, teacher=teacher)
    total = envs.default_budget(env) if steps is None else steps
    if preset in ("paper", "tuned"):
        # The task's train_steps (500 on IP/HalfCheetah) belong to the meta schedule (a 3000-step cycle);
        # the DDPG baseline keeps baselines' 50 updates per 100-step cycle on every task.
        train = spec.train_steps if method == "meta" else RunConfig.train_steps
        run = RunConfig(method=method, total_steps=total, rollout_steps=100, train_steps=train)
        cfg = Config(env=EnvConfig(env, source, physics=physics), run=run, meta=meta, preset=preset)
    else:
        ddpg = DDPGConfig(hidden=(256, 256), layer_norm=False, critic_action_layer=0,
                          actor_lr=3e-4, critic_lr=3e-4, critic_l2=0.0, batch_size=256, tau=0.005,
                          normalize_obs=False)
        run = RunConfig(method=method, total_steps=total, rollout_steps=1, train_steps=1, warmup_steps=5000)
        meta = dataclasses.replace(meta, hidden=(256, 256), layer_norm=False)
        if method == "meta":
            # No random warm-up: the teacher is the exploration from the first step.
            run = dataclasses.replace(run, warmup_steps=0)
        cfg = Config(env=EnvConfig(env, source, physics=physics), run=run, ddpg=ddpg,
                     noise=NoiseConfig(kind="normal", stddev=0.1), meta=meta, preset=preset)
    if student == "td3" and preset == "modern" and method != "meta":
        # The TD3 authors' 25k uniformly random steps before the first update (their start_timesteps).
        cfg = dataclasses.replace(cfg, run=dataclasses.replace(cfg.run, warmup_steps=25_000))
    cfg = dataclasses.replace(cfg, student=student)
    if noise is not None:
        cfg = dataclasses.replace(cfg, noise=dataclasses.replace(cfg.noise, kind=noise))
    overrides = overrides or {}
    named = [k for k in overrides if k in IDENTITY_FIELDS]
    if named:
        # These name the run (folder, label, the task's protocol and budget) and are read before overrides.
        raise ValueError(f"{named[0]} cannot be overridden with --set; choose it with the command's "
                         f"{IDENTITY_FIELDS[named[0]]} option")
    if overrides:
        cfg = override(cfg, overrides)
    if preset == "modern" and method == "meta":
        # One student update per stored step and one look-ahead update per D0 step, derived
        # after the overrides so a changed schedule keeps the ratio (unless set explicitly).
        if "run.train_steps" not in overrides:
            cfg = dataclasses.replace(cfg, run=dataclasses.replace(cfg.run, train_steps=cfg.steps_per_cycle))
        if "meta.lookahead_steps" not in overrides:
            cfg = dataclasses.replace(cfg, meta=dataclasses.replace(cfg.meta, lookahead_steps=cfg.meta.explore_steps))
    if preset == "tuned" and method == "meta":
        cfg = _tuned_meta(cfg, overrides)
    if "run.eval_every" not in overrides:
        target = min(spec.eval_every, max(cfg.steps_per_cycle, cfg.run.total_steps // 10))
        every = default_eval_every(cfg.run.total_steps, cfg.steps_per_cycle, target)
        cfg = dataclasses.replace(cfg, run=dataclasses.replace(cfg.run, eval_every=every))
    return cfg


# The tuned preset's changes to the paper preset's Meta schedule, each from a screen cell at 300k steps
# (results/screen/README.md); applied after the overrides, a field that --set names is left as set.
TUNED_META = {
    "run.train_steps": "half the cycle's stored steps (DDPG's 50 updates per 100 stored steps)",
    "meta.lookahead_steps": "the paper preset's student updates per cycle (50; 500 on IP/HalfCheetah)",
    "meta.teacher_steps": "1 (the paper preset: 100 on IP/HalfCheetah)",
}


def _tuned_meta(cfg: Config, overrides: dict[str, Any]) -> Config:
    run, meta = cfg.run, cfg.meta
    if "meta.lookahead_steps" not in overrides:
        meta = dataclasses.replace(meta, lookahead_steps=meta.lookahead_steps or run.train_steps)
    if "meta.teacher_steps" not in overrides:
        meta = dataclasses.replace(meta, teacher_steps=1)
    if "run.train_steps" not in overrides:
        run = dataclasses.replace(run, train_steps=max(1, cfg.steps_per_cycle // 2))
    return dataclasses.replace(cfg, run=run, meta=meta)


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


def override(cfg: Config, overrides: dict[str, Any]) -> Config:
    """Returns ``cfg`` with dotted fields replaced, e.g. ``{'ddpg.tau': '0.005'}``."""
    groups = {f.name for f in dataclasses.fields(Config)}
    for dotted, value in overrides.items():
        parts = dotted.split(".")
        if len(parts) == 1 and parts[0] in _field_types(Config) and parts[0] not in groups:
            cfg = dataclasses.replace(cfg, **{parts[0]: _coerce(value, _field_types(Config)[parts[0]], dotted)})
            continue
        if len(parts) != 2 or parts[0] not in groups:
            raise ValueError(f"unknown config field {dotted!r}; groups: {', '.join(sorted(groups))}")
        group = getattr(cfg, parts[0])
        types = _field_types(type(group))
        if parts[1] not in types:
            raise ValueError(f"unknown config field {dotted!r}; fields of {parts[0]}: {', '.join(types)}")
        group = dataclasses.replace(group, **{parts[1]: _coerce(value, types[parts[1]], dotted)})
        cfg = dataclasses.replace(cfg, **{parts[0]: group})
    return cfg


def _positive(name: str, value: float) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")


def validate(cfg: Config) -> Config:
    """Raises ``ValueError`` with one clear line for a config that cannot run as asked."""
    envs.get_spec(cfg.env.name)
    if cfg.env.source not in envs.SOURCES:
        raise ValueError(f"unknown source {cfg.env.source!r}; valid sources: {', '.join(envs.SOURCES)}")
    envs.check_physics(cfg.env.name, cfg.env.source, cfg.env.physics)
    _check_method(cfg.run.method)
    _check_student(cfg.student)
    if cfg.td3.policy_noise < 0 or cfg.td3.noise_clip < 0 or cfg.td3.policy_delay <= 0:
        raise ValueError("td3.policy_noise and td3.noise_clip must be >= 0 and td3.policy_delay positive")
    if cfg.preset not in PRESETS:
        raise ValueError(f"unknown preset {cfg.preset!r}; valid presets: {', '.join(PRESETS)}")
    if cfg.noise.kind not in NOISES:
        raise ValueError(f"unknown noise {cfg.noise.kind!r}; valid noises: {', '.join(NOISES)}")
    if cfg.meta.teacher not in TEACHERS:
        raise ValueError(f"unknown teacher {cfg.meta.teacher!r}; valid teachers: {', '.join(TEACHERS)}")
    if cfg.meta.student_from not in STUDENT_FROM:
        raise ValueError(f"meta.student_from must be one of {', '.join(STUDENT_FROM)}, got {cfg.meta.student_from!r}")
    if cfg.meta.baseline not in BASELINES:
        raise ValueError(f"meta.baseline must be one of {', '.join(BASELINES)}, got {cfg.meta.baseline!r}")
    if cfg.env.episode_length < 0:
        raise ValueError(f"env.episode_length must be >= 0 (0 = the task's), got {cfg.env.episode_length}")
    for name in ("total_steps", "rollout_steps", "train_steps", "eval_every", "eval_episodes"):
        _positive(f"run.{name}", getattr(cfg.run, name))
    if cfg.run.warmup_steps < 0 or cfg.run.buffer_size < 0 or cfg.meta.lookahead_steps < 0:
        raise ValueError("run.warmup_steps, run.buffer_size and meta.lookahead_steps must be >= 0")
    if cfg.run.method == "ddpg" and cfg.run.warmup_steps and cfg.run.warmup_steps >= cfg.run.total_steps:
        # (Meta's warm-up only holds back the student's own updates; the teacher explores from the start.)
        raise ValueError(f"run.warmup_steps={cfg.run.warmup_steps} is not below the budget of {cfg.run.total_steps} "
                         f"env steps: the DDPG run would act at random throughout (lower it with "
                         f"--set run.warmup_steps=N, or raise --steps)")
    for name in ("actor_lr", "critic_lr", "batch_size", "tau", "gamma", "obs_clip"):
        _positive(f"ddpg.{name}", getattr(cfg.ddpg, name))
    if not cfg.ddpg.hidden or min(cfg.ddpg.hidden) <= 0:
        raise ValueError(f"ddpg.hidden must be a non-empty tuple of positive widths, got {cfg.ddpg.hidden}")
    if not 0 <= cfg.ddpg.critic_action_layer < len(cfg.ddpg.hidden):
        raise ValueError(f"ddpg.critic_action_layer must be in [0, {len(cfg.ddpg.hidden)}), got {cfg.ddpg.critic_action_layer}")
    if cfg.ddpg.tau > 1 or cfg.ddpg.gamma > 1:
        raise ValueError("ddpg.tau and ddpg.gamma must be <= 1")
    if cfg.ddpg.critic_l2 < 0 or not math.isfinite(cfg.ddpg.critic_l2):
        raise ValueError(f"ddpg.critic_l2 must be >= 0, got {cfg.ddpg.critic_l2}")
    if cfg.noise.kind != "none":
        _positive("noise.stddev", cfg.noise.stddev)
    _positive("noise.adapt_every", cfg.noise.adapt_every)
    if not (math.isfinite(cfg.ddpg.final_init) and cfg.ddpg.final_init >= 0):
        raise ValueError(f"ddpg.final_init must be a finite number >= 0, got {cfg.ddpg.final_init!r}")
    if cfg.noise.kind == "ou":
        _positive("noise.ou_dt", cfg.noise.ou_dt)
        if not (math.isfinite(cfg.noise.ou_theta) and cfg.noise.ou_theta >= 0):
            raise ValueError(f"noise.ou_theta must be a finite number >= 0, got {cfg.noise.ou_theta!r}")
    if cfg.noise.kind == "adaptive-param" and not (math.isfinite(cfg.noise.adapt_coef) and cfg.noise.adapt_coef >= 1):
        raise ValueError(f"noise.adapt_coef must be a finite number >= 1 (the stddev is multiplied or divided by "
                         f"it; 1 keeps it fixed), got {cfg.noise.adapt_coef!r}")
    _positive("meta.visit_samples", cfg.meta.visit_samples)
    if cfg.run.method == "meta":
        for name in ("explore_steps", "eval_steps", "teacher_steps", "eval_envs"):
            _positive(f"meta.{name}", getattr(cfg.meta, name))
        # meta.lr = 0 freezes the teacher at its initialisation (a control: the data without the learning).
        if not (math.isfinite(cfg.meta.lr) and cfg.meta.lr >= 0):
            raise ValueError(f"meta.lr must be a finite number >= 0 (0 = a frozen teacher), got {cfg.meta.lr!r}")
        if not cfg.meta.hidden or min(cfg.meta.hidden) <= 0:
            raise ValueError(f"meta.hidden must be a non-empty tuple of positive widths, got {cfg.meta.hidden}")
        if not cfg.meta.min_log_std < cfg.meta.init_log_std < cfg.meta.max_log_std:
            raise ValueError("meta log-std bounds must satisfy min_log_std < init_log_std < max_log_std")
    cycle = cfg.steps_per_cycle
    if cfg.run.total_steps % cycle:
        raise ValueError(f"run.total_steps={cfg.run.total_steps} is not a multiple of the {cycle} env steps "
                         f"one {cfg.run.method} cycle stores")
    if cfg.run.eval_every % cycle:
        raise ValueError(f"run.eval_every={cfg.run.eval_every} is not a multiple of the {cycle} env steps "
                         f"one {cfg.run.method} cycle stores")
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
    """The config as plain JSON-able nested dicts (tuples become lists)."""
    return json_roundtrip(dataclasses.asdict(cfg))


def json_roundtrip(obj: Any) -> Any:
    import json

    return json.loads(json.dumps(obj))


def from_dict(d: dict[str, Any]) -> Config:
    """Inverse of ``to_dict`` (used to resume a run from its stored config)."""
    groups = {}
    for f in dataclasses.fields(Config):
        if f.name not in d:
            continue
        if dataclasses.is_dataclass(f.default):
            cls = type(f.default)
            types = _field_types(cls)
            unknown = set(d[f.name]) - set(types)
            if unknown:
                raise ValueError(f"stored config has unknown fields {sorted(unknown)} in group {f.name!r}")
            groups[f.name] = cls(**{k: _coerce(v, types[k], f"{f.name}.{k}") for k, v in d[f.name].items()})
        else:
            groups[f.name] = d[f.name]
    return Config(**groups)


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
