"""Environment registry: ``envs.make(name, **overrides)`` -> a wrapped Brax ``Env``.

Tasks are the paper's six. Pendulum is our JAX port of gymnasium's
Pendulum-v1; the five MuJoCo tasks are gymnasium's v5 models
(``source='gymnasium'``, the default and the reference) stepped by MJX
(``physics='mjx'``) or by MuJoCo's own C engine from inside the program
(``physics='mujoco'``, envs/mujoco_c.py; ``physics='auto'``, the command lines'
default, picks it on a CPU: ``resolve_physics``), or, as an explicit fast
option, brax's own simplified versions on MJX (``source='brax'``). Every env
takes actions in [-1, 1] and is wrapped for the time limit, auto-reset and
episode statistics (see ``envs/wrappers.py``).

``TASKS`` also carries each task's per-paper protocol (budget, meta schedule),
used by the experiment presets.

Any other gymnasium MuJoCo env runs as ``gym:<Id>`` (e.g. ``gym:Walker2d-v5``, with keyword arguments
``gym:Ant-v5(ctrl_cost_weight=0.1)``): gymnasium's own env, its observation, reward, termination and reset
computed by its own code on the host, stepped on MuJoCo's C engine only (``envs/gym_generic.py``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import io

# mujoco.mjx prints "Failed to import warp" on import when its optional GPU (Warp) backend is
# not installed; that is expected here, so its stdout is swallowed for this one import.
with contextlib.redirect_stdout(io.StringIO()):
    from brax.envs.base import Env

from envs.wrappers import AutoResetWrapper, EpisodeWrapper


@dataclasses.dataclass(frozen=True)
class TaskSpec:
    """What the paper and gymnasium fix per task."""

    gym_id: str            # gymnasium id the default source reproduces
    episode_length: int    # gymnasium's TimeLimit
    paper_budget: int      # total env steps per seed in the paper (section 5.1)
    # Default evaluation interval in env steps; a multiple of the built-in explorers' cycles (the noise
    # baseline's 100 steps, the teacher's 300 or 3000) so that they report at the same sample counts and
    # the default budget is reachable.
    eval_every: int = 15_000


TASKS: dict[str, TaskSpec] = {
    "pendulum": TaskSpec("Pendulum-v1", 200, 900_000, eval_every=9_000),
    "inverted_pendulum": TaskSpec("InvertedPendulum-v5", 1000, 1_500_000),
    "inverted_double_pendulum": TaskSpec("InvertedDoublePendulum-v5", 1000, 1_500_000),
    "hopper": TaskSpec("Hopper-v5", 1000, 1_000_000),
    "halfcheetah": TaskSpec("HalfCheetah-v5", 1000, 1_500_000),
    "reacher": TaskSpec("Reacher-v5", 50, 700_000, eval_every=6_000),
}

SOURCES = ("gymnasium", "brax")
# Physics engines of the gymnasium MuJoCo tasks: MJX (JAX, float32; any accelerator) or MuJoCo's own
# C engine called from inside the program (float64, gymnasium's numbers; host CPU). See envs/mujoco_c.py.
PHYSICS = ("mjx", "mujoco")
# What the command lines accept: an engine, or "auto" (resolve_physics), their default.
PHYSICS_CHOICES = ("auto", *PHYSICS)


def is_gym_task(name: str) -> bool:
    """A ``gym:<Id>`` task: any gymnasium MuJoCo env, on the C engine only (``envs/gym_generic.py``)."""
    return name.startswith("gym:")


def resolve_physics(name: str, source: str, physics: str, backend: str | None = None) -> str:
    """The engine ``physics='auto'`` means; any other value is returned unchanged.

    'auto' is MuJoCo's C engine for a gymnasium MuJoCo task where JAX's default backend is the CPU
    (measured on 2 CPU cores: the main job compiled 8.0x and trained 2.3x faster there than on MJX;
    results/benchmarks/BENCHMARKS.md, "The main job"), and MJX on accelerators (the C engine runs on the host CPU), for brax's
    models (MJX only) and for Pendulum (a JAX task: its value is irrelevant and stays 'mjx'). A ``gym:`` task
    has the C engine only: 'auto' is 'mujoco' on every backend.

    Args:
      name, source: the task and its model source.
      physics: 'auto', 'mjx' or 'mujoco'.
      backend: JAX's default backend ('cpu', 'gpu', 'tpu'); default: ``jax.default_backend()``.
    """
    if physics != "auto":
        return physics
    if is_gym_task(name):
        return "mujoco"
    if name == "pendulum" or source != "gymnasium":
        return "mjx"
    if backend is None:
        import jax

        backend = jax.default_backend()
    return "mujoco" if backend == "cpu" else "mjx"


def default_budget(name: str) -> int:
    """The paper's budget rounded down to a whole number of evaluation intervals.

    Equal to the paper's for pendulum, IP, IDP and HalfCheetah; Hopper gets
    990k instead of 1M and Reacher 696k instead of 700k, because the meta
    cycle (300 steps) does not divide the paper's numbers. A ``gym:`` task has no
    paper budget: 1M (``envs.gym_generic.DEFAULT_BUDGET``), i.e. 990k.
    """
    spec = get_spec(name)
    return (spec.paper_budget // spec.eval_every) * spec.eval_every


def get_spec(name: str) -> TaskSpec:
    """The task's protocol; ``ValueError`` (one line) for an unknown task, or a ``gym:`` id that is not a
    registered gymnasium MuJoCo env (checked without building it)."""
    if is_gym_task(name):
        from envs.gym_generic import task_spec

        return task_spec(name)
    if name not in TASKS:
        raise ValueError(f"unknown task {name!r}; valid tasks: {', '.join(TASKS)}, or gym:<Id> for any "
                         f"gymnasium MuJoCo env (e.g. gym:Walker2d-v5)")
    return TASKS[name]


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
    if physics == "mujoco" and name == "pendulum":
        raise ValueError("pendulum is a JAX task without MuJoCo physics: --physics=mujoco applies to the "
                         "five MuJoCo tasks (use the default for pendulum)")
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
    if name == "pendulum":
        if source != "gymnasium":
            raise ValueError("pendulum has only the gymnasium source (our JAX port of Pendulum-v1)")
        from envs.pendulum import Pendulum

        return Pendulum(**overrides)
    from envs import brax_mujoco, gym_mujoco

    table = gym_mujoco.GYMNASIUM_TASKS if source == "gymnasium" else brax_mujoco.BRAX_TASKS
    task = table[name](**overrides)
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
      episode_length: time limit; default gymnasium's (1000; Reacher 50; Pendulum 200).
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
