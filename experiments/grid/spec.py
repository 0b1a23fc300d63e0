"""A grid's cell as typed data: how a cell explores and learns (``Method``) and everything that defines its run
(``CellSpec``). A spec yields the run's ``Config`` directly, with no command line in between; ``CellSpec.argv``
writes the same run as ``experiments.run`` options, for the cell's record (``reproduce.json``), for
``experiments.verify`` and for a run in another process. ``tests/test_grid_spec.py`` checks that the two give the
same config for every grid method."""

from __future__ import annotations

import dataclasses

from metapg_jax.config import Config
from metapg_jax.host.runner import TERM_GRACE


@dataclasses.dataclass(frozen=True)
class Method:
    """A grid method: what ``experiments.run`` options a cell of it has besides the grid's own.

    Attributes:
      explorer: ``--method`` (the registered explorer: ``ddpg``, ``meta``, ``own`` or a plug-in's).
      flags: the explorer's shortcuts (``--teacher``, ``--noise``; ``metapg_jax.strategy.flags``) as
        (flag, value) pairs, in command-line order.
      overrides: ``GROUP.FIELD=VALUE`` settings (``--set``), applied in order before the grid's own.
      preset: a preset of its own that the cell runs under whatever the grid's (the tuned teacher's), or None.
    """

    explorer: str
    flags: tuple[tuple[str, str], ...] = ()
    overrides: tuple[str, ...] = ()
    preset: str | None = None

    def setting(self, *items: str) -> Method:
        """The same method with ``items`` (``GROUP.FIELD=VALUE``) applied after its own overrides."""
        return dataclasses.replace(self, overrides=(*self.overrides, *items))

    def options(self) -> list[str]:
        """The method as ``experiments.run`` options: ``--method``, its shortcuts, then ``--set`` per override
        (the preset is the cell's: ``CellSpec.argv``)."""
        out = [f"--method={self.explorer}", *(f"--{flag}={value}" for flag, value in self.flags)]
        for item in self.overrides:
            out += ["--set", item]
        return out


def method(explorer: str, *overrides: str, preset: str | None = None, **flags: str) -> Method:
    """``Method(explorer, flags, overrides, preset)`` written as a call: ``method("ddpg", "noise.stddev=0.1",
    noise="normal")``."""
    return Method(explorer, tuple(flags.items()), tuple(overrides), preset)


@dataclasses.dataclass(frozen=True)
class CellSpec:
    """Everything that defines a grid cell's run; the cell's folder and how it is run (checkpoint cadence,
    progress bars) are the grid's.

    Attributes:
      task: the task (``envs``' name or ``gym:<Id>``).
      method: how it explores (``Method``).
      preset: the grid's preset (``paper``, ``modern``, ``tuned``); the method's own wins (``run_preset``).
      student: the learner (``ddpg``, ``td3``, ``sac`` or a plug-in's).
      seeds, seed: seeds per cell and the base PRNG seed.
      steps: env steps per seed; None: the task's paper budget (``envs.default_budget``).
      source: the MuJoCo models' source (``gymnasium`` or ``brax``).
      physics: the MuJoCo tasks' engine (``mjx``, ``mujoco`` or ``auto``); a task without a choice of engine
        (Pendulum, JAX physics) runs on its own whatever this says.
      overrides: the grid's ``GROUP.FIELD=VALUE`` settings, after the method's.
      plugins: ``--plugin`` modules or files the run imports.
    """

    task: str
    method: Method
    preset: str = "paper"
    student: str = "ddpg"
    seeds: int = 8
    seed: int = 0
    steps: int | None = None
    source: str = "gymnasium"
    physics: str = "auto"
    overrides: tuple[str, ...] = ()
    plugins: tuple[str, ...] = ()

    @property
    def run_preset(self) -> str:
        """The preset the cell runs under: the method's own, else the grid's."""
        return self.method.preset or self.preset

    @property
    def has_engine_choice(self) -> bool:
        """Whether the task is stepped by a MuJoCo engine that ``physics`` chooses (not a JAX task)."""
        import envs

        return envs.has_mujoco(self.task)

    def budget(self) -> int:
        """Env steps per seed: ``steps``, else the task's paper budget (as ``make_config``)."""
        from envs import default_budget

        return default_budget(self.task) if self.steps is None else self.steps

    def with_steps(self, steps: int | None) -> CellSpec:
        return dataclasses.replace(self, steps=steps)

    def run_args(self) -> dict:
        """The run-defining arguments as ``experiments.run`` stores them (``experiments.training.args.RUN_ARGS``,
        ``config.json``'s ``run_args``) before ``physics`` is resolved."""
        from experiments.training import args as training_args

        a = training_args.defaults()
        a.update(env=self.task, method=self.method.explorer, **dict(self.method.flags), preset=self.run_preset,
                 seeds=self.seeds, seed=self.seed, steps=self.steps, source=self.source,
                 physics=self.physics if self.has_engine_choice else a["physics"], student=self.student,
                 overrides=[*self.method.overrides, *self.overrides], plugins=list(self.plugins))
        return a

    def config(self) -> Config:
        """The run's validated config; ``ValueError`` (one line) for a bad one."""
        from experiments.training import args as training_args

        return training_args.config_from_run_args(self.run_args())

    def argv(self, explicit_steps: bool = False) -> list[str]:
        """The run-defining ``experiments.run`` options (no folder, no run options): the task, the method's
        options, the preset, seeds, base seed, source, the engine where the task has a choice, the student where
        it is not ``experiments.run``'s default, the budget where it was given (or ``explicit_steps``), then the
        grid's ``--set``s. ``experiments.run.build_parser().parse_args(spec.argv())`` gives ``config()``."""
        from experiments.training.args import RUN_ARGS

        out = [f"--env={self.task}", *self.method.options(), f"--preset={self.run_preset}", f"--seeds={self.seeds}",
               f"--seed={self.seed}", f"--source={self.source}"]
        if self.has_engine_choice:  # named always: experiments.run's own default, 'auto', depends on the backend
            out.append(f"--physics={self.physics}")
        if self.student != RUN_ARGS["student"]:
            out.append(f"--student={self.student}")
        if self.steps is not None or explicit_steps:
            out.append(f"--steps={self.budget()}")
        for item in self.overrides:
            out += ["--set", item]
        for plugin in self.plugins:
            out.append(f"--plugin={plugin}")
        return out


@dataclasses.dataclass(frozen=True)
class GridSpec:
    """What every cell of a grid shares of its run (``CellSpec``'s fields but the task and the method)."""

    preset: str = "paper"
    student: str = "ddpg"
    seeds: int = 8
    seed: int = 0
    steps: int | None = None
    source: str = "gymnasium"
    physics: str = "auto"
    overrides: tuple[str, ...] = ()

    def cell(self, task: str, method: Method) -> CellSpec:
        """The run of the grid's cell of ``task`` and ``method``."""
        return CellSpec(task, method, **dataclasses.asdict(self))


@dataclasses.dataclass(frozen=True)
class GridRun:
    """Where a grid keeps its cells and how it runs them (what is not the cells' runs).

    Attributes:
      runs_dir: the run folders' root: ``<runs_dir>/<preset>/<task>/<name>``.
      results_dir: the archive's and the artefacts' root: ``<results_dir>[/<preset>]/cells/<task>/<name>``
        (``experiments.analysis.cells.archive_dir_for``).
      preset: the grid's preset, which names its folders (a method's own preset does not).
      baseline: the grid method whose visitation sample the archive keeps beside Meta's.
      quiet, no_plot, tensorboard, checkpoint_every, checkpoint_minutes, term_grace: ``experiments.run``'s options
        of every cell (no progress bars; no per-run PNGs; TensorBoard scalars; the checkpoint cadence; what a SIGTERM
        leaves a cell's run to finish its chunk in flight and checkpoint it).
    """

    runs_dir: str
    results_dir: str
    preset: str = "paper"
    baseline: str = "ddpg-paramnoise"
    quiet: bool = False
    no_plot: bool = False
    tensorboard: bool = False
    checkpoint_every: int = 0
    checkpoint_minutes: float = 5.0
    term_grace: float = TERM_GRACE

    def run_options(self) -> list[str]:
        """The ``experiments.run`` options that say how each cell runs (none of them changes its numbers); those at
        their defaults are left out, so the recorded command lines keep their form."""
        out = [flag for flag, on in (("--no-plot", self.no_plot), ("--quiet", self.quiet),
                                     ("--tensorboard", self.tensorboard)) if on]
        if self.checkpoint_every:
            out.append(f"--checkpoint-every={self.checkpoint_every}")
        if self.checkpoint_minutes != 5.0:
            out.append(f"--checkpoint-minutes={self.checkpoint_minutes:g}")
        if self.term_grace != TERM_GRACE:
            out.append(f"--term-grace={self.term_grace:g}")
        return out
