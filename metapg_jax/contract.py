"""The plug-in contract's classes: what a student and an explorer are (:class:`Student`, :class:`Explorer`,
:class:`ActingExplorer`, each with a default for every optional hook), and the checks that refuse a strategy
outside it. ``metapg_jax.strategy`` (the registry) re-exports them.

The object is checked when a ``metapg_jax.loop.Trainer`` is built with it, and at registration where ``make``
is the class itself (:func:`check_student`, :func:`check_explorer`); before anything compiles, a one-line
``ValueError`` refuses

* a student that does not derive from :class:`Student`, an explorer that derives from neither
  :class:`ActingExplorer` nor :class:`Explorer`;
* a required hook left to the base: a student's ``init``, ``normalize``, ``actor_apply``,
  ``deterministic_policy``, ``update`` (and, on an object, ``obs_size`` and ``action_size``); an explorer's
  ``init`` and ``act`` (an ``ActingExplorer``) or ``cycle`` (an ``Explorer``);
* an ``ActingExplorer`` with a ``cycle`` of its own, and an ``Explorer`` with a hook that only an
  ``ActingExplorer`` has (``act``, ``episode_start``, ``adapt``, ``adapt_every``, ``metrics``: its cycle is its
  own, and nothing would run them);
* a misspelt hook: a public name of the class (a method, an attribute, a dataclass field) or of the object
  that is not a hook of its base but is close to one (difflib's ratio at least ``MISSPELT``, 0.8), e.g.
  ``episode_starts``, ``metric``, ``adapt_evry``, ``normalise``. A helper whose name comes that close starts
  with ``_`` (private names are not checked).
"""

from __future__ import annotations

import dataclasses
import difflib
import inspect
from typing import Any, Callable


class Student:
    """An off-policy learner: the base class of every student. ``init``, ``normalize``, ``actor_apply``,
    ``deterministic_policy`` and ``update`` are required, and the attributes ``obs_size`` and ``action_size``;
    ``guarded_params`` has a default, and ``sample_action`` is a stochastic student's only. All methods are pure
    and jittable; anything random lives in the state (a key), so that Algorithm 1's look-ahead copy of the state
    copies it.

    Attributes:
      obs_size, action_size: the env's sizes (actions are in [-1, 1]).
    """

    obs_size: int
    action_size: int
    _REQUIRED = ("obs_size", "action_size", "init", "normalize", "actor_apply", "deterministic_policy", "update")

    def init(self, key: Any) -> Any:
        """Args: a PRNG key. Returns: the state, a pytree whose ``.actor`` holds the actor's parameters (what
        exploration perturbs or reads, what is evaluated and exported)."""
        raise NotImplementedError

    def normalize(self, normalizer: Any, obs: Any) -> Any:
        """Args: the running observation normaliser, raw observations. Returns: what the networks see."""
        raise NotImplementedError

    def actor_apply(self, actor: Any, obs_normalized: Any) -> Any:
        """Args: actor parameters, normalised observations. Returns: actions in [-1, 1]."""
        raise NotImplementedError

    def deterministic_policy(self, actor: Any, normalizer: Any) -> Callable[[Any], Any]:
        """Returns: ``obs -> action`` on raw observations (evaluation, the look-ahead rollout D1)."""
        raise NotImplementedError

    def update(self, state: Any, normalizer: Any, batch: Any) -> tuple[Any, dict]:
        """One update on a replay minibatch (``metapg_jax.types.Transition``).

        Returns: (the new state, a dict of scalar metrics: chunk means in ``metrics.jsonl``)."""
        raise NotImplementedError

    def sample_action(self, actor: Any, obs_normalized: Any, z: Any) -> Any:
        """A stochastic student's only (its spec says ``stochastic=True``): its policy's action in [-1, 1] for
        one normalised observation, with ``z`` (shape ``(action_size,)``, standard normal at each step, white or
        colored) as the sampling noise (SAC: tanh(mean + std * z)). ``--method=own`` explores with it."""
        raise NotImplementedError(f"{type(self).__name__} is deterministic: it has no sample_action")

    def guarded_params(self, state: Any) -> Any:
        """Args: the student's state. Returns: the parameters the NaN guard requires finite after every cycle
        (``metrics['finite']``). Default: ``state.actor``."""
        return state.actor


class Explorer:
    """An explorer with a cycle of its own, as a scan body, and the base class of every explorer: the teacher of
    Algorithm 1 (whose data also trains a look-ahead copy of the student and the teacher itself). ``init`` and
    ``cycle`` are required, ``guarded_params`` has a default."""

    _REQUIRED = ("init", "cycle")

    def init(self, trainer: Any, student_state: Any, key: Any) -> Any:
        """Args: the ``metapg_jax.loop.Trainer``, the freshly initialised student state, a PRNG key.
        Returns: the explorer's part of a seed's ``TrainState`` (``state.explorer``, its *carry*; a pytree)."""
        raise NotImplementedError

    def cycle(self, trainer: Any, state: Any) -> tuple[Any, dict]:
        """One cycle, built from the loop's stages: collect in ``trainer.env`` (``metapg_jax.rollout.rollout``),
        ``trainer.store`` the data (exactly ``steps_per_cycle`` env steps; ``source='student'`` for the
        student's own rollouts), train the student (``trainer.student_updates``).

        Args: the trainer, a seed's ``TrainState``. Returns: (the new state, a dict of scalar metrics)."""
        raise NotImplementedError

    def guarded_params(self, carry: Any) -> Any:
        """Args: the carry. Returns: the parameters of it the NaN guard requires finite after every cycle, beside
        the student's (the teacher's). Default: none, ``()``."""
        return ()


class ActingExplorer(Explorer):
    """An explorer that only chooses actions; its cycle is the loop's (``metapg_jax.loop.Trainer.acting_cycle``):
    ``steps_per_cycle`` env steps of ``act``, stored, then ``run.train_steps`` student updates. The DDPG
    baselines' noise is one (``metapg_jax.strategies.noise``). ``init`` and ``act`` are required; the other
    hooks have defaults that do nothing (no episode starts, no adaptation, no metrics), and the loop leaves out
    the work of ``episode_start`` and ``adapt`` where they are the defaults."""

    _REQUIRED = ("init", "act")
    adapt_every: int = 0  # ``adapt`` runs before every ``adapt_every`` student updates (0: never)

    def cycle(self, trainer: Any, state: Any) -> tuple[Any, dict]:
        """The loop's ``trainer.acting_cycle(state)`` (not overridden: an explorer with a cycle of its own
        derives from :class:`Explorer`)."""
        return trainer.acting_cycle(state)

    def act(self, trainer: Any, carry: Any, student_state: Any, normalizer: Any, obs: Any, key: Any) -> tuple[Any, Any]:
        """One env step's action. Args: the trainer, the carry, the student's state and the normaliser as the
        cycle began, one raw observation, a PRNG key. Returns: (an action in [-1, 1], the new carry)."""
        raise NotImplementedError

    def episode_start(self, trainer: Any, carry: Any, student_state: Any, key: Any) -> Any:
        """Returns: the carry for an episode that starts at this step (OU's reset, a new parameter
        perturbation); run only on steps where some seed starts an episode. Default: the carry unchanged (and
        the loop runs nothing at episode starts)."""
        del trainer, student_state, key
        return carry

    def adapt(self, trainer: Any, carry: Any, student_state: Any, normalizer: Any, batch: Any, key: Any) -> Any:
        """Args: as ``act``, with a replay minibatch (``Transition``) instead of an observation and the
        normaliser after this cycle's data. Returns: the new carry (adaptive parameter noise's stddev). Default:
        the carry unchanged."""
        del trainer, student_state, normalizer, batch, key
        return carry

    def metrics(self, carry: Any) -> dict:
        """Returns: scalar metrics of the carry, added to the cycle's. Default: none."""
        del carry
        return {}


# A public name of a strategy's class this similar to a hook's (difflib's ratio), and not a hook, is a misspelt hook.
MISSPELT = 0.8


def _class(obj: Any) -> type:
    return obj if isinstance(obj, type) else type(obj)


def _hooks(base: type) -> set[str]:
    """The public methods and attributes of a base class and its bases."""
    return {name for klass in base.__mro__[:-1] for name in [*vars(klass), *inspect.get_annotations(klass)]
            if not name.startswith("_")}


def _names(obj: Any, base: type) -> set[str]:
    """The public names a strategy's class (and the object, if it is one) adds to ``base``."""
    cls = _class(obj)
    names = {name for klass in cls.__mro__ if klass not in base.__mro__ for name in vars(klass)}
    if dataclasses.is_dataclass(cls):
        names.update(f.name for f in dataclasses.fields(cls))
    if not isinstance(obj, type):
        names.update(getattr(obj, "__dict__", {}))
    return {name for name in names if not name.startswith("_")}


def _check(obj: Any, role: str, base: type, family: type) -> None:
    """The rule of the module docstring for ``obj`` (a class or an object) that derives from ``base``; ``family``
    is the base whose hooks count as misspellings too (``ActingExplorer``'s for any explorer)."""
    cls, hooks = _class(obj), _hooks(base)

    def lacks(name: str) -> bool:
        if any(name in vars(klass) for klass in base.__mro__):  # a method the base declares
            return getattr(cls, name) is getattr(base, name)
        return not isinstance(obj, type) and not hasattr(obj, name)  # an attribute (of objects only)

    missing = [name for name in base._REQUIRED if lacks(name)]
    if missing:
        raise ValueError(f"{role} {cls.__name__} lacks {', '.join(missing)} (required of a strategy.{base.__name__})")
    for name in sorted(_names(obj, base) - hooks):
        if name in _hooks(family):
            raise ValueError(f"{role} {cls.__name__} defines {name}, a hook of strategy.{family.__name__} that "
                             f"nothing runs for a strategy.{base.__name__} (a cycle of its own)")
        close = difflib.get_close_matches(name, sorted(_hooks(family)), n=1, cutoff=MISSPELT)
        if close:
            raise ValueError(f"{role} {cls.__name__}: {name!r} is not a hook of strategy.{base.__name__} "
                             f"(did you mean {close[0]!r}?)")


def check_student(student: Any) -> None:
    """A one-line ``ValueError`` unless ``student`` (an object or its class) keeps the contract (module docstring)."""
    if not issubclass(_class(student), Student):
        raise ValueError(f"student {_class(student).__name__} does not derive from strategy.Student")
    _check(student, "student", Student, Student)


def check_explorer(explorer: Any) -> None:
    """A one-line ``ValueError`` unless ``explorer`` (an object or its class) keeps the contract (module
    docstring)."""
    cls = _class(explorer)
    if not issubclass(cls, Explorer):
        raise ValueError(f"explorer {cls.__name__} derives from neither strategy.ActingExplorer (it chooses actions) "
                         f"nor strategy.Explorer (a cycle of its own)")
    if issubclass(cls, ActingExplorer) and cls.cycle is not ActingExplorer.cycle:
        raise ValueError(f"explorer {cls.__name__} defines cycle: an ActingExplorer's cycle is the loop's, an "
                         f"explorer with a cycle of its own derives from strategy.Explorer")
    _check(explorer, "explorer", ActingExplorer if issubclass(cls, ActingExplorer) else Explorer, ActingExplorer)
