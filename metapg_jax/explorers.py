"""Explorers by name: who collects the student's data, and what they do with it.

An explorer is an object with two pure, jittable methods (``metapg_jax.loop`` calls them):

* ``init(trainer, student_state, key) -> explorer_state``: its part of a seed's ``TrainState``
  (``state.explorer``; a pytree), given the freshly initialised student;
* ``cycle(trainer, state) -> (state, metrics)``: one cycle: collect data in ``trainer.env``
  (``metapg_jax.rollout.rollout`` with a policy that may read ``state.student.actor`` and carry
  per-env state with per-episode-start hooks), store it (``trainer.store``), train the student
  (``trainer.student_updates``, with a hook between blocks of updates if the explorer adapts), and
  return a dict of scalar metrics (they go to ``metrics.jsonl`` as chunk means).

Built in: ``ddpg`` (``metapg_jax.noise.NoiseExplorer``: the DDPG baselines' action or parameter
noise) and ``meta`` (``metapg_jax.meta.TeacherExplorer``: Algorithm 1). The name is
``config.run.method``. A new explorer is one file that defines the class and calls
``register(name, factory)``, ``factory(config) -> explorer``.
"""

from __future__ import annotations

from typing import Any, Callable, Protocol

from metapg_jax.config import Config, register_method


class Explorer(Protocol):
    def init(self, trainer: Any, student_state: Any, key: Any) -> Any: ...

    def cycle(self, trainer: Any, state: Any) -> tuple[Any, dict]: ...


_FACTORIES: dict[str, Callable[[Config], Explorer]] = {}


def register(name: str, factory: Callable[[Config], Explorer]) -> None:
    """Makes ``factory(config)`` the explorer of ``run.method == name`` (its cycle stores
    ``run.rollout_steps`` env steps: ``Config.steps_per_cycle``)."""
    _FACTORIES[name] = factory
    register_method(name)


def make(config: Config) -> Explorer:
    """The explorer of ``config.run.method``."""
    try:
        factory = _FACTORIES[config.run.method]
    except KeyError:
        raise ValueError(f"unknown method {config.run.method!r}; registered: {', '.join(sorted(_FACTORIES))}") from None
    return factory(config)


def _builtins() -> None:
    from metapg_jax.meta import TeacherExplorer
    from metapg_jax.noise import NoiseExplorer

    register("ddpg", lambda config: NoiseExplorer(config.noise))
    register("meta", lambda config: TeacherExplorer(config.meta))


_builtins()
