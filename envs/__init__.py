"""Environment registry: ``envs.make(name, **overrides)`` -> a wrapped Brax ``Env``.

A built-in task is one ``TaskSpec`` in ``TASKS``: its constructor, display name, gymnasium id and time
limit, the paper's budget, meta schedule and Table 2 numbers where the paper has them, and its default
evaluation interval. Everything else (the config's defaults, Meta's schedule, the experiments' task lists
and table names) reads the spec; adding a task is adding its entry (and its env's code) here.

The built-in tasks are the paper's six and MountainCarContinuous. Pendulum and MountainCarContinuous
are our JAX ports of gymnasium's Pendulum-v1 and MountainCarContinuous-v0; the five MuJoCo tasks are
gymnasium's v5 models (``source='gymnasium'``, the default and the reference) stepped by MJX
(``physics='mjx'``) or by MuJoCo's own C engine from inside the program
(``physics='mujoco'``, envs/mujoco_c.py; ``physics='auto'``, the command lines'
default, picks it on a CPU: ``resolve_physics``), or, as an explicit fast
option, brax's own simplified versions on MJX (``source='brax'``). Every env
takes actions in [-1, 1] and is wrapped for the time limit, auto-reset and
episode statistics (see ``envs/wrappers.py``).

Any other gymnasium MuJoCo env runs as ``gym:<Id>`` (e.g. ``gym:Walker2d-v5``, with keyword arguments
``gym:Ant-v5(ctrl_cost_weight=0.1)``): gymnasium's own env, its observation, reward, termination and reset
computed by its own code on the host, stepped on MuJoCo's C engine only (``envs/gym_generic.py``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib
import io
from typing import Callable

# mujoco.mjx prints "Failed to import warp" on import when its optional GPU (Warp) backend is
# not installed; that is expected here, so its stdout is swallowed for this one import.
with contextlib.redirect_stdout(io.StringIO()):
    from brax.envs.base import Env

from envs.wrappers import AutoResetWrapper, EpisodeWrapper


@dataclasses.dataclass(frozen=True)
class MetaSchedule:
    """Algorithm 1's cycle where the paper gives a task its own (section 5.1); what ``--method=meta`` runs on
    the task under the paper preset."""

    explore_steps: int   # |D0| per cycle
    eval_steps: int      # |D1| per cycle, per eval env
    train_steps: int     # the student's DDPG updates per cycle (and the look-ahead's)
    teacher_steps: int   # REINFORCE Adam steps per cycle


@dataclasses.dataclass(frozen=True)
class Table2Row:
    """A task's row of the paper's Table 2 (Xu et al., 2018): final return, mean and std over 3 seeds, on gym's
    v1 task (Pendulum-v0)."""

    position: int                # the row's place in Table 2 (1 = first): the order the paper's grid lists tasks in
    meta: tuple[float, float]    # Meta: mean, std
    ddpg: tuple[float, float]    # DDPG: mean, std


@dataclasses.dataclass(frozen=True)
class TaskSpec:
    """A task: how ``make`` builds it, and what the paper and gymnasium fix for it."""

    gym_id: str            # gymnasium id the default source reproduces
    episode_length: int    # gymnasium's TimeLimit
    paper_budget: int      # total env steps per seed in the paper (section 5.1); else the default budget
    # Default evaluation interval in env steps; a multiple of the built-in explorers' cycles (the noise
    # baseline's 100 steps, the teacher's 300 or 3000) so that they report at the same sample counts and
    # the default budget is reachable.
    eval_every: int = 15_000
    display_name: str = ""                # how tables and figures name the task ("HalfCheetah")
    # The env of source 'gymnasium', as "module:attribute" (imported on first use): called with the keyword
    # arguments of ``make``, it returns the task without wrappers.
    entry_point: str = ""
    brax_name: str | None = None          # brax's own env of source 'brax' (None: the gymnasium source only)
    mujoco: bool = True                   # stepped by MuJoCo (MJX or the C engine); False: a JAX task
    meta_schedule: MetaSchedule | None = None   # the paper's own cycle for the task; None: Algorithm 1's defaults
    table2: Table2Row | None = None       # the paper's Table 2 numbers; None: a task the paper did not run
    # The normalised score's 1 where the task fixes one (experiments.normalisation): the most an episode can
    # return, or the return that counts as solved. Table 2's tasks have one too (gymnasium's solved threshold;
    # Pendulum, which has none, its maximum), but their default anchors take the 1 from a reference grid's cell;
    # ``python -m experiments.normalisation --fixed-references`` uses these (the dense set normalised as the hard one).
    reference_return: float | None = None
    reference: str = ""                   # what that 1 is, in words


# The paper's longer cycle (section 5.1: Half-Cheetah and Inverted Pendulum "need more explore rollout steps
# (1000) to finish the task", with 2000 evaluation steps, 500 student updates and 100 teacher updates per cycle);
# the other tasks keep Algorithm 1's defaults (100, 200, 50, 1; metapg_jax/strategies/meta.py).
_LONG_CYCLE = MetaSchedule(explore_steps=1000, eval_steps=2000, train_steps=500, teacher_steps=100)

_SOLVED = "gymnasium's solved threshold (reward_threshold of {})"

TASKS: dict[str, TaskSpec] = {
    "pendulum": TaskSpec(
        "Pendulum-v1", 200, 900_000, eval_every=9_000, display_name="Pendulum",
        entry_point="envs.pendulum:Pendulum", mujoco=False, reference_return=0.0,
        reference="its maximum, the most an episode can return (every step's cost is at least 0; Pendulum-v1 has no "
                  "solved threshold)",
        table2=Table2Row(4, meta=(-123.0, 10.0), ddpg=(-206.0, 31.0))),
    "inverted_pendulum": TaskSpec(
        "InvertedPendulum-v5", 1000, 1_500_000, display_name="InvertedPendulum",
        entry_point="envs.gym_mujoco:InvertedPendulum", brax_name="inverted_pendulum", meta_schedule=_LONG_CYCLE,
        reference_return=950.0, reference=_SOLVED.format("InvertedPendulum-v5"),
        table2=Table2Row(2, meta=(745.0, 27.0), ddpg=(499.0, 23.0))),
    "inverted_double_pendulum": TaskSpec(
        "InvertedDoublePendulum-v5", 1000, 1_500_000, display_name="InvertedDoublePendulum",
        entry_point="envs.gym_mujoco:InvertedDoublePendulum", brax_name="inverted_double_pendulum",
        reference_return=9100.0, reference=_SOLVED.format("InvertedDoublePendulum-v5"),
        table2=Table2Row(1, meta=(7718.0, 277.0), ddpg=(2795.0, 1325.0))),
    "hopper": TaskSpec(
        "Hopper-v5", 1000, 1_000_000, display_name="Hopper",
        entry_point="envs.gym_mujoco:Hopper", brax_name="hopper",
        reference_return=3800.0, reference=_SOLVED.format("Hopper-v5"),
        table2=Table2Row(3, meta=(205.0, 41.0), ddpg=(135.0, 42.0))),
    "halfcheetah": TaskSpec(
        "HalfCheetah-v5", 1000, 1_500_000, display_name="HalfCheetah",
        entry_point="envs.gym_mujoco:HalfCheetah", brax_name="halfcheetah", meta_schedule=_LONG_CYCLE,
        reference_return=4800.0, reference=_SOLVED.format("HalfCheetah-v5"),
        table2=Table2Row(5, meta=(2011.0, 339.0), ddpg=(1594.0, 298.0))),
    "reacher": TaskSpec(
        "Reacher-v5", 50, 700_000, eval_every=6_000, display_name="Reacher",
        entry_point="envs.gym_mujoco:Reacher", brax_name="reacher",
        reference_return=-3.75, reference=_SOLVED.format("Reacher-v5"),
        table2=Table2Row(6, meta=(-12.16, 1.19), ddpg=(-11.67, 3.39))),
    # Not in the paper: a sparse reward, where exploration decides the outcome (envs/mountain_car.py). No paper
    # budget: 60k steps (60 episodes' worth at the time limit), evaluated every 3k (20 evaluations). Its
    # normalised 1 is gymnasium's solved threshold (the spec's reward_threshold, 90): reaching the flag pays 100
    # less the actions' cost, so a solving episode returns a little under 100.
    "mountain_car_continuous": TaskSpec(
        "MountainCarContinuous-v0", 999, 60_000, eval_every=3_000, display_name="MountainCarContinuous",
        entry_point="envs.mountain_car:MountainCarContinuous", mujoco=False, reference_return=90.0,
        reference=_SOLVED.format("MountainCarContinuous-v0")),
}
# The task a config names when none is given (``metapg_jax.config.make_config``, ``experiments.run``).
DEFAULT_TASK = "pendulum"

SOURCES = ("gymnasium", "brax")
# Physics engines of the gymnasium MuJoCo tasks: MJX (JAX, float32; any accelerator) or MuJoCo's own
# C engine called from inside the program (float64, gymnasium's numbers; host CPU). See envs/mujoco_c.py.
PHYSICS = ("mjx", "mujoco")
# What the command lines accept: an engine, or "auto" (resolve_physics), their default.
PHYSICS_CHOICES = ("auto", *PHYSICS)


def is_dmc_task(name: str) -> bool:
    """A ``dmc:<domain>-<task>`` task: DeepMind Control suite's, on both engines (``envs/dmc.py``)."""
    return name.startswith("dmc:")


def is_gym_task(name: str) -> bool:
    """A ``gym:<Id>`` task: any gymnasium MuJoCo env, on the C engine only (``envs/gym_generic.py``)."""
    return name.startswith("gym:")


def resolve_physics(name: str, source: str, physics: str, backend: str | None = None) -> str:
    """The engine ``physics='auto'`` means; any other value is returned unchanged.

    'auto' is MuJoCo's C engine for a gymnasium MuJoCo task where JAX's default backend is the CPU
    (measured on 2 CPU cores: the main job compiled 8.0x and trained 2.3x faster there than on MJX;
    results/benchmarks/BENCHMARKS.md, "The main job"), and MJX on accelerators (the C engine runs on the host CPU), for brax's
    models (MJX only) and for a JAX task (Pendulum, MountainCarContinuous: its value is irrelevant and stays
    'mjx'). A ``gym:`` task has the C engine only: 'auto' is 'mujoco' on every backend.

    Args:
      name, source: the task and its model source.
      physics: 'auto', 'mjx' or 'mujoco'.
      backend: JAX's default backend ('cpu', 'gpu', 'tpu'); default: ``jax.default_backend()``.
    """
    if physics != "auto":
        return physics
    if is_gym_task(name):
        return "mujoco"
    spec = TASKS.get(name)
    if (spec is not None and not spec.mujoco) or source != "gymnasium":
        return "mjx"
    if backend is None:
        import jax

        backend = jax.default_backend()
    return "mujoco" if backend == "cpu" else "mjx"


def default_budget(name: str) -> int:
    """The paper's budget rounded down to a whole number of evaluation intervals.

    Equal to the paper's for pendulum, IP, IDP and HalfCheetah; Hopper gets
    990k instead of 1M and Reacher 696k instead of 700k, because the meta
    cycle (300 steps) does not divide the paper's numbers. MountainCarContinuous,
    not in the paper, has its spec's 60k. A ``gym:`` task has no
    paper budget: 1M (``envs.gym_names.DEFAULT_BUDGET``), i.e. 990k.
    """
    spec = get_spec(name)
    return (spec.paper_budget // spec.eval_every) * spec.eval_every


def get_spec(name: str) -> TaskSpec:
    """The task's protocol; ``ValueError`` (one line) for an unknown task, or a ``gym:`` id that is not a
    registered gymnasium MuJoCo env (checked without building it)."""
    if is_gym_task(name):
        from envs.gym_names import task_spec

        return task_spec(name)
    if is_dmc_task(name):
        from envs.dmc_names import task_spec as dmc_spec

        return dmc_spec(name)
    if name not in TASKS:
        raise ValueError(f"unknown task {name!r}; valid tasks: {', '.join(TASKS)}, gym:<Id> for any "
                         f"gymnasium MuJoCo env (e.g. gym:Walker2d-v5), or dmc:<domain>-<task> (DeepMind Control, "
                         f"e.g. dmc:cartpole-swingup)")
    return TASKS[name]


def display_name(name: str) -> str:
    """How tables and figures name a task: its spec's ``display_name``, or a ``gym:`` task's gymnasium id with its
    arguments (not checked against gymnasium); ``ValueError`` (one line) for an unknown task."""
    if is_gym_task(name):
        return name[len("gym:"):]
    return get_spec(name).display_name  # a dmc: task's is its name without the prefix


def has_mujoco(name: str) -> bool:
    """Whether MuJoCo steps the task (MJX or the C engine): every ``gym:`` task, and a built-in one whose spec says
    so; False for a JAX task (Pendulum, MountainCarContinuous)."""
    return is_gym_task(name) or get_spec(name).mujoco


def paper_tasks() -> tuple[str, ...]:
    """The built-in tasks of the paper's Table 2, in its order."""
    rows = {name: spec.table2.position for name, spec in TASKS.items() if spec.table2 is not None}
    return tuple(sorted(rows, key=rows.__getitem__))


def constructor(name: str, source: str = "gymnasium") -> Callable[..., Env]:
    """What builds a built-in task without wrappers from keyword arguments: its spec's ``entry_point`` (source
    'gymnasium') or brax's own env (``'brax'``); ``ValueError`` (one line) for a task the source lacks."""
    spec = get_spec(name)
    if source == "brax":
        if spec.brax_name is None:
            raise ValueError(f"{name} has only the gymnasium source (brax has no {spec.display_name})")
        from envs.brax_mujoco import brax_task

        return brax_task(spec.brax_name)
    if is_dmc_task(name):
        from envs.dmc_names import constructor as dmc_constructor

        return dmc_constructor(name)
    module, attribute = spec.entry_point.split(":")
    return getattr(importlib.import_module(module), attribute)


def check_physics(name: str, source: str, physics: str) -> None:
    """Raises ``ValueError`` (one line) for an engine the task or source cannot use."""
    if physics not in PHYSICS:
        raise ValueError(f"unknown physics {physics!r}; valid physics: {', '.join(PHYSICS_CHOICES)}")
    if is_gym_task(name):
        if source != "gymnasium":
            raise ValueError(f"{name} is gymnasium's own env: --source={source} does not apply (use the default, "
                             f"--source=gymnasium)")
        if physics != "mujoco":
            raise ValueError(f"{name} runs on MuJoCo's C engine only (--physics=mujoco): its observation, reward "
                             f"and termination are gymnasium's own Python code, called on the host every step, "
                             f"which MJX (traced into the program) cannot run")
        return
    if is_dmc_task(name) and source != "gymnasium":
        raise ValueError(f"{name} is a DeepMind Control task on dm_control's model: --source={source} does not "
                         f"apply (use the default, --source=gymnasium)")
    if physics == "mujoco" and not get_spec(name).mujoco:
        raise ValueError(f"{name} is a JAX task without MuJoCo physics: --physics=mujoco applies to the "
                         f"MuJoCo tasks (use the default for {name})")
    if physics == "mujoco" and source != "gymnasium":
        raise ValueError(f"--physics=mujoco steps gymnasium's models; source {source!r} has only MJX "
                         f"(use --source=gymnasium or --physics=mjx)")


def make_raw(name: str, source: str = "gymnasium", physics: str = "mjx", physics_threads: int | None = None,
             **overrides) -> Env:
    """The task without wrappers (no time limit, no auto-reset)."""
    get_spec(name)
    if source not in SOURCES:
        raise ValueError(f"unknown source {source!r}; valid sources: {', '.join(SOURCES)}")
    physics = resolve_physics(name, source, physics)
    check_physics(name, source, physics)
    if is_gym_task(name):
        from envs.gym_generic import GymnasiumCEnv

        return GymnasiumCEnv(name, threads=physics_threads, **overrides)
    task = constructor(name, source)(**overrides)
    if physics == "mujoco":
        from envs.mujoco_c import MujocoCEnv

        return MujocoCEnv(task, threads=physics_threads)
    return task


def make(name: str, source: str = "gymnasium", episode_length: int | None = None, physics: str = "mjx",
         physics_threads: int | None = None, **overrides) -> Env:
    """A task wrapped for training: time limit, auto-reset, episode statistics.

    Args:
      name: one of ``TASKS``, or ``gym:<Id>`` (any gymnasium MuJoCo env; ``physics='mujoco'`` or 'auto').
      source: ``'gymnasium'`` (default: gymnasium's v5 model) or ``'brax'`` (brax's own, MJX only).
      episode_length: time limit; default gymnasium's (1000; Reacher 50; Pendulum 200;
        MountainCarContinuous 999).
      physics: ``'mjx'`` (default), ``'mujoco'`` (MuJoCo's C engine, envs/mujoco_c.py) or ``'auto'``
        (``resolve_physics``: the C engine where JAX runs on the CPU).
      physics_threads: the C engine's threads per batch (default: the CPUs this process may use).
      **overrides: keyword arguments of the task class (e.g. ``reset_noise_scale``); for a ``gym:`` task,
        of ``gymnasium.make`` (added to those in the name).
    """
    spec = get_spec(name)
    env = make_raw(name, source, physics, physics_threads, **overrides)
    length = spec.episode_length if episode_length is None else episode_length
    return AutoResetWrapper(EpisodeWrapper(env, length))
