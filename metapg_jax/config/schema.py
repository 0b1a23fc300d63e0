"""The configuration's types: the core groups (``env``, ``run``, ``ddpg``) as frozen dataclasses, ``Config`` (the
core groups, every strategy's group by name, and the values derived from them), the presets' names."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import envs
from metapg_jax import strategy

PRESETS = ("paper", "modern", "tuned")
# Fields that make_config's own arguments set (with the task's protocol and budget): not overridable.
IDENTITY_FIELDS = {"preset": "preset", "env.name": "task", "run.method": "method", "student": "student"}
CORE_GROUPS = ("env", "run", "ddpg")


@dataclasses.dataclass(frozen=True)
class EnvConfig:
    name: str = envs.DEFAULT_TASK     # task, one of envs.TASKS, or gym:<Id>[(kwargs)] (any gymnasium MuJoCo env)
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


def positive(name: str, value: float) -> None:
    """A one-line ``ValueError`` unless ``value`` is a positive finite number (the checks of every group)."""
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
