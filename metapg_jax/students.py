"""Students by name: the off-policy learners an explorer collects data for.

A student is an object (``metapg_jax.loop`` and the explorers use nothing else of it) with

* ``obs_size`` and ``action_size`` (ints; actions are in [-1, 1]);
* ``init(key) -> state``: a pytree with the actor's parameters as ``state.actor`` (what the variance
  teacher and parameter noise read, what is exported) and, if it has one, the critic's as
  ``state.critic`` (both are NaN-guarded);
* ``normalize(normalizer, obs)``: observations as the networks see them (``metapg_jax.normalizer``);
* ``actor_apply(actor, obs_normalized) -> action`` and ``deterministic_policy(actor, normalizer)``
  (``obs -> action`` on raw observations: evaluation, the look-ahead rollout D1, export);
* ``update(state, normalizer, batch) -> (state, metrics)``: one update on a replay minibatch
  (``metapg_jax.types.Transition``); ``metrics`` is a dict of scalars (chunk means in ``metrics.jsonl``).
  Anything random lives in the state (a key), so the look-ahead copy of Algorithm 1 copies it.

All of them pure and jittable. Built in: ``ddpg`` (``metapg_jax.ddpg.DDPG``) and ``td3``
(``metapg_jax.td3.TD3``); both build on ``metapg_jax.ddpg.ActorCritic`` (the ``ddpg`` config group's
networks, optimisers, normalisation and acting), which is the quickest start for a new one, and
whose actor network ``policy.npz`` export reproduces. The name is ``config.student``. A new student
is one file that defines the class and calls ``register(name, factory)``,
``factory(config, obs_size, action_size) -> student``.
"""

from __future__ import annotations

from typing import Any, Callable, Protocol

from metapg_jax.config import Config, register_student


class Student(Protocol):
    obs_size: int
    action_size: int

    def init(self, key: Any) -> Any: ...

    def normalize(self, normalizer: Any, obs: Any) -> Any: ...

    def actor_apply(self, actor: Any, obs_normalized: Any) -> Any: ...

    def deterministic_policy(self, actor: Any, normalizer: Any) -> Callable[[Any], Any]: ...

    def update(self, state: Any, normalizer: Any, batch: Any) -> tuple[Any, dict]: ...


_FACTORIES: dict[str, Callable[[Config, int, int], Student]] = {}


def register(name: str, factory: Callable[[Config, int, int], Student]) -> None:
    """Makes ``factory(config, obs_size, action_size)`` the student of ``config.student == name``."""
    _FACTORIES[name] = factory
    register_student(name)


def make(config: Config, obs_size: int, action_size: int) -> Student:
    """The student of ``config.student`` for an env with these sizes."""
    try:
        factory = _FACTORIES[config.student]
    except KeyError:
        raise ValueError(f"unknown student {config.student!r}; registered: {', '.join(sorted(_FACTORIES))}") from None
    return factory(config, obs_size, action_size)


def _builtins() -> None:
    from metapg_jax.ddpg import DDPG
    from metapg_jax.td3 import TD3

    register("ddpg", lambda config, obs, act: DDPG(config.ddpg, obs, act))
    register("td3", lambda config, obs, act: TD3(config.ddpg, obs, act, td3=config.td3))


_builtins()
