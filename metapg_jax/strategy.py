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

The base classes and the checks that refuse a strategy outside the contract are ``metapg_jax.contract``'s
(re-exported here: ``strategy.ActingExplorer`` is ``contract.ActingExplorer``).
"""

from __future__ import annotations

import dataclasses
import importlib
import pkgutil
from typing import Any, Callable

# The contract, re-exported: plug-ins derive from strategy.ActingExplorer, strategy.Student, ...
from metapg_jax.contract import ActingExplorer, Explorer, Student, check_explorer, check_student  # noqa: F401


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
