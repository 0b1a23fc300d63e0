"""A ``gym:<Id>`` task's name (``envs/gym_generic.py`` runs the task): its parsing (the gymnasium id and keyword
arguments), its checks against gymnasium's registry (a MuJoCo env, keyword arguments it takes, a time limit), its
``envs.TaskSpec``, and gymnasium's own env of it. Cheap: nothing is simulated."""

from __future__ import annotations

import ast
import functools
import inspect
import numbers
import re
from typing import Any

from envs import TaskSpec

__all__ = ["DEFAULT_BUDGET", "make_gymnasium_env", "parse_name", "task_spec"]


# A gym: task's default budget (no paper budget exists for it): 1M env steps per seed, the common budget of
# MuJoCo locomotion benchmarks; envs.default_budget rounds it down to whole evaluation intervals (990k).
DEFAULT_BUDGET = 1_000_000


_NAME = re.compile(r"gym:([^()\s]+)(?:\((.*)\))?", re.DOTALL)


def _literal(node: ast.AST) -> Any:
    """A keyword argument's value: a Python literal, with ``inf`` and ``nan`` (``ValueError`` otherwise)."""
    if isinstance(node, ast.Name) and node.id in ("inf", "nan"):
        return float(node.id)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        value = _literal(node.operand)
        if isinstance(value, numbers.Number) and not isinstance(value, bool):
            return -value if isinstance(node.op, ast.USub) else value
    if isinstance(node, (ast.Tuple, ast.List)):
        values = [_literal(e) for e in node.elts]
        return tuple(values) if isinstance(node, ast.Tuple) else values
    return ast.literal_eval(node)


@functools.lru_cache(maxsize=None)
def parse_name(name: str) -> tuple[str, tuple[tuple[str, Any], ...]]:
    """``'gym:Ant-v5(ctrl_cost_weight=0.1)'`` -> ``('Ant-v5', (('ctrl_cost_weight', 0.1),))``; ``ValueError``
    (one line) for a malformed name."""
    m = _NAME.fullmatch(name)
    if m is None:
        raise ValueError(f"bad task name {name!r}: expected gym:<gymnasium id> or gym:<id>(key=value, ...), "
                         f"e.g. gym:Walker2d-v5")
    gym_id, args = m.group(1), m.group(2)
    if not args or not args.strip():
        return gym_id, ()
    try:
        call = ast.parse(f"f({args})", mode="eval").body
    except SyntaxError:
        raise ValueError(f"{name}: the keyword arguments are not Python syntax (write them as key=value, "
                         f"...)") from None
    if call.args or any(k.arg is None for k in call.keywords):
        raise ValueError(f"{name}: only keyword arguments (key=value) can follow the id")
    kwargs = []
    for k in call.keywords:
        try:
            kwargs.append((k.arg, _literal(k.value)))
        except (ValueError, TypeError):
            raise ValueError(f"{name}: {k.arg}={ast.unparse(k.value)} is not a literal (numbers, True/False/None, "
                             f"'strings', tuples; inf and nan)") from None
    names = [k for k, _ in kwargs]
    if len(set(names)) != len(names):
        raise ValueError(f"{name}: a keyword argument is given twice")
    return gym_id, tuple(kwargs)


def _env_class(name: str, gym_id: str):
    """The registered env's class, checked to be a MuJoCo env of the ``mujoco`` package."""
    import gymnasium
    from gymnasium.envs.mujoco import MujocoEnv
    from gymnasium.envs.registration import load_env_creator

    spec = gymnasium.envs.registry.get(gym_id)
    if spec is None:
        import difflib

        close = difflib.get_close_matches(gym_id, list(gymnasium.envs.registry), n=1, cutoff=0.8)
        hint = f" (did you mean gym:{close[0]}?)" if close else ""
        raise ValueError(f"unknown task {name!r}: gymnasium has no env {gym_id!r}{hint}")
    entry = spec.entry_point
    try:
        creator = load_env_creator(entry) if isinstance(entry, str) else entry
    except Exception as err:  # a registered module that cannot be imported here
        raise ValueError(f"{name}: cannot load {gym_id}'s entry point {entry}: "
                         f"{type(err).__name__}: {err}".splitlines()[0]) from None
    if not (isinstance(creator, type) and issubclass(creator, MujocoEnv)):
        what = entry if isinstance(entry, str) else getattr(entry, "__name__", repr(entry))
        raise ValueError(f"{name}: {gym_id} is not a MuJoCo env (its entry point {what} is not a "
                         f"gymnasium.envs.mujoco.MujocoEnv); gym: tasks are gymnasium's MuJoCo envs, run on "
                         f"MuJoCo's C engine")
    return spec, creator


@functools.lru_cache(maxsize=None)
def task_spec(name: str):
    """The ``envs.TaskSpec`` of a ``gym:`` task; ``ValueError`` (one line) for an unknown or non-MuJoCo id, or a
    keyword argument the env does not take. Cheap: nothing is built (the id's module is imported)."""
    gym_id, kwargs = parse_name(name)
    spec, cls = _env_class(name, gym_id)
    from gymnasium.envs.mujoco import MujocoEnv

    def takes(c) -> list[str]:
        return [p.name for p in inspect.signature(c.__init__).parameters.values()
                if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and p.name != "self"]

    unknown = [k for k, _ in kwargs if k not in takes(cls) + takes(MujocoEnv)]
    if unknown:
        raise ValueError(f"{name}: {gym_id} takes no keyword argument {unknown[0]!r} "
                         f"(its own: {', '.join(takes(cls))})")
    if spec.max_episode_steps is None:
        raise ValueError(f"{name}: {gym_id} is registered without a time limit (max_episode_steps)")
    return TaskSpec(gym_id, int(spec.max_episode_steps), DEFAULT_BUDGET, display_name=name[len("gym:"):])


def make_gymnasium_env(name: str, **overrides):
    """gymnasium's own env of a ``gym:`` task, unwrapped (no time limit, order or checker wrappers): the
    instance the host steps, and the tests' reference. ``overrides`` add to the name's keyword arguments."""
    import gymnasium

    from envs.mujoco_base import without_the_settotalmass_warning

    task_spec(name)
    gym_id, kwargs = parse_name(name)
    kwargs = {**dict(kwargs), **overrides}
    try:
        with without_the_settotalmass_warning():
            return gymnasium.make(gym_id, disable_env_checker=True, **kwargs).unwrapped
    except Exception as err:  # a keyword argument's value the env cannot take, a missing asset, ...
        raise ValueError(f"{name}: gymnasium.make({gym_id!r}, **{kwargs}) failed: "
                         f"{type(err).__name__}: {err}".splitlines()[0]) from None
