"""A ``dmc:<domain>-<task>`` task's name (DeepMind Control suite, ``envs/dmc.py`` runs the task): the tasks we
provide, their parsing, their ``envs.TaskSpec`` and the one-line refusals. Cheap: nothing is built, and dm_control
is not imported (only looked for)."""

from __future__ import annotations

import importlib.util
import re

from envs import TaskSpec

__all__ = ["DEFAULT_BUDGET", "EPISODE_LENGTH", "EVAL_EVERY", "TASKS", "parse_name", "require_dm_control",
           "constructor", "task_spec"]

# dm_control's suite names -> "module:class" of our task and its keyword arguments. A later batch of domains
# adds its rows here (and its classes in a module of its own, on envs/dmc.py's DmcTask).
TASKS: dict[str, tuple[str, dict]] = {
    "cartpole-balance": ("envs.dmc_classic:Cartpole", {"swing_up": False, "sparse": False}),
    "cartpole-balance_sparse": ("envs.dmc_classic:Cartpole", {"swing_up": False, "sparse": True}),
    "cartpole-swingup": ("envs.dmc_classic:Cartpole", {"swing_up": True, "sparse": False}),
    "cartpole-swingup_sparse": ("envs.dmc_classic:Cartpole", {"swing_up": True, "sparse": True}),
    "pendulum-swingup": ("envs.dmc_classic:Pendulum", {}),
    "ball_in_cup-catch": ("envs.dmc_classic:BallInCup", {}),
    "reacher-easy": ("envs.dmc_classic:Reacher", {"target_size": 0.05}),
    "reacher-hard": ("envs.dmc_classic:Reacher", {"target_size": 0.015}),
    "point_mass-easy": ("envs.dmc_classic:PointMass", {}),
    "acrobot-swingup": ("envs.dmc_classic:Acrobot", {"sparse": False}),
    "acrobot-swingup_sparse": ("envs.dmc_classic:Acrobot", {"sparse": True}),
    "finger-spin": ("envs.dmc_finger:Finger", {"turn": False}),
    "finger-turn_easy": ("envs.dmc_finger:Finger", {"turn": True, "target_radius": 0.07}),
    "finger-turn_hard": ("envs.dmc_finger:Finger", {"turn": True, "target_radius": 0.03}),
    "hopper-stand": ("envs.dmc_locomotion:Hopper", {"hopping": False}),
    "hopper-hop": ("envs.dmc_locomotion:Hopper", {"hopping": True}),
    "walker-stand": ("envs.dmc_locomotion:Walker", {"move_speed": 0.0}),
    "walker-walk": ("envs.dmc_locomotion:Walker", {"move_speed": 1.0}),
    "walker-run": ("envs.dmc_locomotion:Walker", {"move_speed": 8.0}),
    "cheetah-run": ("envs.dmc_locomotion:Cheetah", {}),
}

# Every task here ends at dm_control's time limit only (its tasks' ``get_termination`` is None): 1,000 control
# steps (10 s of cartpole, acrobot and cheetah, 25 s of walker, 20 s of the others).
EPISODE_LENGTH = 1000
# No paper budget exists for these tasks: 500k env steps per seed (500 episodes). The evaluation interval is a
# multiple of every built-in explorer's cycle (100, 300 and 3,000 steps: envs.TaskSpec), so 9k, the multiple of
# 3k nearest to 10k (55 evaluations); envs.default_budget rounds the budget down to whole intervals, 495k.
DEFAULT_BUDGET = 500_000
EVAL_EVERY = 9_000

_NAME = re.compile(r"dmc:([a-z_]+)-([a-z_]+)")
INSTALL = 'pip install -e ".[dmc]"'


def require_dm_control(name: str) -> None:
    """``ValueError`` (one line) naming the install command when dm_control, which holds the models, is missing."""
    if importlib.util.find_spec("dm_control") is None:
        raise ValueError(f"{name} needs the dm_control package (DeepMind Control suite's models): {INSTALL}")


def parse_name(name: str) -> tuple[str, str]:
    """``'dmc:cartpole-swingup'`` -> ``('cartpole', 'swingup')``; ``ValueError`` (one line) for a malformed name,
    an unknown domain or an unknown task of a known domain."""
    m = _NAME.fullmatch(name)
    if m is None:
        raise ValueError(f"bad task name {name!r}: expected dmc:<domain>-<task> with dm_control's names, e.g. "
                         f"dmc:cartpole-swingup")
    domain, task = m.groups()
    domains = sorted({k.split("-")[0] for k in TASKS})
    if domain not in domains:
        raise ValueError(f"unknown task {name!r}: no DeepMind Control domain {domain!r} here; domains: "
                         f"{', '.join(domains)}")
    if f"{domain}-{task}" not in TASKS:
        tasks = [k.split("-")[1] for k in TASKS if k.startswith(domain + "-")]
        raise ValueError(f"unknown task {name!r}: domain {domain} has the tasks {', '.join(tasks)}")
    return domain, task


def constructor(name: str):
    """What builds a ``dmc:`` task's env without wrappers from keyword arguments (its class, with its task's)."""
    import functools
    import importlib

    domain, task = parse_name(name)
    require_dm_control(name)
    entry, kwargs = TASKS[f"{domain}-{task}"]
    module, attribute = entry.split(":")
    return functools.partial(getattr(importlib.import_module(module), attribute), **kwargs)


def task_spec(name: str) -> TaskSpec:
    """The ``envs.TaskSpec`` of a ``dmc:`` task (``ValueError``, one line, for a bad name or without dm_control)."""
    domain, task = parse_name(name)
    require_dm_control(name)
    return TaskSpec(f"{domain}-{task}", EPISODE_LENGTH, DEFAULT_BUDGET, eval_every=EVAL_EVERY,
                    display_name=name[len("dmc:"):], entry_point=TASKS[f"{domain}-{task}"][0],
                    reference_return=float(EPISODE_LENGTH),
                    reference=f"the suite's maximum: a reward of at most 1 per step over the {EPISODE_LENGTH:,}-step "
                              f"episode")
