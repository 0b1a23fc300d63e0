"""The plug-in contract: what a student and an explorer are, what else a strategy declares, and the one
registry per kind.

A *strategy* is a student (the off-policy learner) or an explorer (who collects its data). Each is one file
that defines the class, its config group and its schedule, and registers a spec here. The built-in ones are
the modules of ``metapg_jax.strategies``, found and imported the first time the registry is asked
(:func:`load_builtins`; nothing else imports them); a user's file registers itself when ``--plugin FILE.py``
imports it. The rest of the package asks the registry and neither imports a strategy nor branches on its
name (``tests/test_strategy.py``): ``config`` for the groups, schedules and checks, ``train`` for the
objects, the commands for the cycle metrics, labels and flags.

A strategy's contract in brief:

* the object (``make``): an instance of a subclass of :class:`Student`, or of :class:`ActingExplorer` (it
  chooses actions; the loop runs the cycle) or :class:`Explorer` (a cycle of its own) below; pure and
  jittable. The base classes give every optional hook a default (an explorer without episode starts,
  adaptation or metrics inherits ones that do nothing), so the loop calls every hook without asking whether it
  is there;
* its config group (``group``: a frozen dataclass, or None): ``config.<name>`` of every config, stored in
  config.json, set with ``--set <name>.<field>=V``, type-checked by ``config.override``;
* ``group_defaults(config) -> group``: the group's defaults for the config's task and preset (every config
  has every registered group, the chosen strategies' and the others');
* ``schedule(config) -> config``: what choosing the strategy changes elsewhere (before ``--set``), and
  ``derive(config, overrides) -> config`` (after ``--set``: fields derived from others, unless set);
* ``validate(config)``: one-line ``ValueError`` for bad values, before anything compiles;
* students: ``architecture(config)``, how the exported ``policy.npz`` describes the acting policy, and
  ``stochastic`` (a policy it samples with ``sample_action``: ``--method=own`` explores with it);
* explorers: ``steps_per_cycle(config)`` (env steps one cycle stores; default ``run.rollout_steps``), the
  per-cycle metrics written to ``cycles.jsonl`` (``cycle_metrics``) and the panels of their plot, a label
  for run names, and a command-line shortcut for one field (``flag``, e.g. ``--teacher``; a plug-in's too,
  as the commands import ``--plugin`` files before they build their parsers); an explorer may read another's
  group instead of one of its own (``uses_group``: ``own`` reads ``noise``) and share its shortcut.

A part of a strategy with settings of its own that is neither a student nor an explorer (an action-noise kind
of ``metapg_jax.action_noise``, e.g. ``pink``) registers its group alone (``register_group``).

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
import importlib
import inspect
import pkgutil
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


def _keep(config: Any, *_: Any) -> Any:
    return config


def _no_checks(config: Any) -> None:
    return None


@dataclasses.dataclass(frozen=True)
class StudentSpec:
    """A student by name (``--student``). ``make(config, obs_size, action_size) -> Student``."""

    name: str
    make: Callable[[Any, int, int], Student]
    group: type | None = None                                   # its config group's dataclass; named ``name``
    group_defaults: Callable[[Any], Any] | None = None          # config -> group (default: ``group()``)
    schedule: Callable[[Any], Any] = _keep                      # config -> config, when chosen, before --set
    derive: Callable[[Any, dict], Any] = _keep                  # (config, overrides) -> config, after --set
    validate: Callable[[Any], None] = _no_checks
    # config -> how ``policy.npz`` describes the acting policy to its NumPy loader (``metapg_jax.host.policy``);
    # None: the ``ActorCritic`` actor of the ``ddpg`` group (``metapg_jax.actor_critic.actor_architecture``).
    architecture: Callable[[Any], dict] | None = None
    # True: the student's policy is stochastic and it has ``sample_action`` (it explores with --method=own).
    stochastic: bool = False
    summary: str = ""                                           # a few words for --help

    @property
    def group_key(self) -> str | None:
        return self.name if self.group is not None else None


@dataclasses.dataclass(frozen=True)
class ExplorerSpec:
    """An explorer by name (``--method``). ``make(config) -> Explorer``."""

    name: str
    make: Callable[[Any], Explorer]
    group: type | None = None
    group_name: str | None = None                               # default: ``name``
    # Another explorer's group this one reads instead of a group of its own (its shortcut then sets that group).
    uses_group: str | None = None
    group_defaults: Callable[[Any], Any] | None = None
    schedule: Callable[[Any], Any] = _keep
    derive: Callable[[Any, dict], Any] = _keep
    validate: Callable[[Any], None] = _no_checks
    steps_per_cycle: Callable[[Any], int] | None = None         # default: run.rollout_steps
    cycle_metrics: tuple[str, ...] = ()                         # per cycle to cycles.jsonl (and TensorBoard)
    # Panels of the per-cycle plot (``plot_file`` in the run folder): (metric or metrics, title) each.
    cycle_panels: tuple[tuple[Any, str], ...] = ()
    plot_file: str = "cycles.png"
    label: Callable[[Any], str] | None = None                   # config -> detail of the run's name
    flag: tuple[str, str] | None = None                         # (command-line option, field of its group)
    moved: dict[str, str] = dataclasses.field(default_factory=dict)  # old field of its group -> new dotted name
    summary: str = ""

    @property
    def group_key(self) -> str | None:
        return (self.group_name or self.name) if self.group is not None else None


@dataclasses.dataclass(frozen=True)
class GroupSpec:
    """A config group of a part of a strategy that is not a student or an explorer itself: e.g. an action-noise
    kind of the noise explorer (``metapg_jax.strategies.pink``). Read as ``config.<name>``, set with ``--set``."""

    name: str
    group: type
    group_defaults: Callable[[Any], Any] | None = None
    validate: Callable[[Any], None] = _no_checks

    @property
    def group_key(self) -> str:
        return self.name


_STUDENTS: dict[str, StudentSpec] = {}
_EXPLORERS: dict[str, ExplorerSpec] = {}
_GROUPS: dict[str, GroupSpec] = {}
_LOADED = False


def load_builtins() -> None:
    """Imports every module of ``metapg_jax.strategies`` once (each registers its spec)."""
    global _LOADED
    if _LOADED:
        return
    package = importlib.import_module("metapg_jax.strategies")
    for module in sorted(m.name for m in pkgutil.iter_modules(package.__path__)):
        importlib.import_module(f"metapg_jax.strategies.{module}")
    _LOADED = True  # after every import: one that failed is tried again, not left half-registered


# Names a strategy's group cannot take: the core groups and the other fields and methods of a config (written
# out: config imports this module; tests/test_strategy.py checks the two agree).
RESERVED = frozenset({"env", "run", "ddpg", "groups", "preset", "student", "replace", "explorer_spec",
                      "steps_per_cycle", "cycles_per_chunk", "num_chunks", "buffer_capacity", "episode_length"})


def _check_group(key: str | None, owner: str) -> None:
    if key is None:
        return
    if key in RESERVED or key.startswith("_"):
        raise ValueError(f"config group {key!r} of {owner!r}: the name is taken by the config itself")
    for spec in [*_STUDENTS.values(), *_EXPLORERS.values(), *_GROUPS.values()]:
        if spec.group_key == key and spec.name != owner:
            raise ValueError(f"config group {key!r} is already registered by {spec.name!r}")


def register_student(spec: StudentSpec | str, make: Callable | None = None, **fields: Any) -> StudentSpec:
    """Registers a student: a :class:`StudentSpec`, or its name, ``make`` and spec fields. A name registered
    again is replaced (a plug-in re-imported). A ``make`` that is a class is checked here (:func:`check_student`)."""
    spec = spec if isinstance(spec, StudentSpec) else StudentSpec(spec, make, **fields)
    _check_group(spec.group_key, spec.name)
    if isinstance(spec.make, type):
        check_student(spec.make)
    _STUDENTS[spec.name] = spec
    return spec


def register_explorer(spec: ExplorerSpec | str, make: Callable | None = None, **fields: Any) -> ExplorerSpec:
    """Registers an explorer: an :class:`ExplorerSpec`, or its name, ``make`` and spec fields. A ``make`` that is a
    class is checked here (:func:`check_explorer`)."""
    spec = spec if isinstance(spec, ExplorerSpec) else ExplorerSpec(spec, make, **fields)
    _check_group(spec.group_key, spec.name)
    if isinstance(spec.make, type):
        check_explorer(spec.make)
    _EXPLORERS[spec.name] = spec
    return spec


def register_group(spec: GroupSpec | str, group: type | None = None, **fields: Any) -> GroupSpec:
    """Registers a config group of its own for a part of a strategy (:class:`GroupSpec`, or its name, dataclass
    and spec fields); its ``validate`` runs with every config's checks."""
    spec = spec if isinstance(spec, GroupSpec) else GroupSpec(spec, group, **fields)
    _check_group(spec.group_key, spec.name)
    _GROUPS[spec.name] = spec
    return spec


def students() -> dict[str, StudentSpec]:
    load_builtins()
    return dict(_STUDENTS)


def explorers() -> dict[str, ExplorerSpec]:
    load_builtins()
    return dict(_EXPLORERS)


def student(name: str) -> StudentSpec:
    """The student registered as ``name``; a one-line ``ValueError`` naming the valid ones otherwise."""
    specs = students()
    if name not in specs:
        raise ValueError(f"unknown student {name!r}; valid students: {', '.join(sorted(specs))}")
    return specs[name]


def explorer(name: str) -> ExplorerSpec:
    """The explorer registered as ``name`` (``--method``); a one-line ``ValueError`` otherwise."""
    specs = explorers()
    if name not in specs:
        raise ValueError(f"unknown method {name!r}; valid methods: {', '.join(sorted(specs))}")
    return specs[name]


def extra_groups() -> dict[str, GroupSpec]:
    """The groups registered with :func:`register_group`."""
    load_builtins()
    return dict(_GROUPS)


def groups() -> dict[str, tuple[type, Callable[[Any], Any] | None]]:
    """Every registered config group: {name: (dataclass, group_defaults)}, in registration order (the students',
    the explorers', then those of :func:`register_group`)."""
    return {spec.group_key: (spec.group, spec.group_defaults)
            for spec in [*students().values(), *explorers().values(), *extra_groups().values()]
            if spec.group is not None}


def validators() -> list[Callable[[Any], None]]:
    """Every registered strategy's and group's ``validate``."""
    return [spec.validate for spec in [*students().values(), *explorers().values(), *extra_groups().values()]]


def moved_fields() -> dict[str, str]:
    """Dotted names of fields that moved out of a strategy's group -> where they are now (old configs and
    ``--set`` spellings keep working)."""
    out = {}
    for spec in explorers().values():
        out.update({f"{spec.group_key}.{old}": new for old, new in spec.moved.items()})
    return out


def flags() -> dict[str, tuple[tuple[str, ...], str]]:
    """Command-line shortcuts: {option: (the explorers it applies to, dotted field)}, e.g. ``--teacher``. Two
    explorers may share a shortcut if it sets the same field (``--noise`` of ``ddpg`` and ``own``)."""
    out: dict[str, tuple[tuple[str, ...], str]] = {}
    for spec in explorers().values():
        if not spec.flag:
            continue
        option, field = spec.flag
        dotted = f"{spec.group_key or spec.uses_group}.{field}"
        owners, known = out.get(option, ((), dotted))
        if known != dotted:
            raise ValueError(f"--{option} of {spec.name!r} sets {dotted}, but that of {owners[0]!r} sets {known}")
        out[option] = ((*owners, spec.name), dotted)
    return out
