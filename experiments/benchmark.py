"""The exploration benchmark in one command: which exploration should an off-policy learner use, and by how much
does it matter? Plans students x strategies x tasks x seeds at a budget, runs the cells (or resumes, or skips
them), archives each with its provenance and rebuilds ``results/<name>/``.

    python -m experiments.benchmark --dry-run --no-calibrate     # the plan: each cell's state and command
    python -m experiments.benchmark --dry-run                    # the same with a calibrated CPU-time estimate
    python -m experiments.benchmark                              # the default plan (many CPU hours), resumable
    python -m experiments.benchmark --tasks hopper,gym:Walker2d-v5 --students td3 --strategies td3-pink,meta-independent
    python -m experiments.benchmark --launcher ray --ray-address auto
    python -m experiments.benchmark --artefacts-only             # rebuild results/exploration from what is stored

The default plan: the paper's six tasks (``experiments.grid.methods.tasks``), both students (TD3, SAC) with every one
of their strategies (``experiments.grid.methods.STRATEGIES``: TD3 with Gaussian, Ornstein-Uhlenbeck, adaptive
parameter and colored noise, per-episode noise scales, the paper's teacher and the tuned teacher; SAC with its own
policy, white or colored, and the paper's teacher), 10 seeds per cell from base seed 1000 (one no earlier grid in
``results/`` used), 300,000 env steps per seed, MuJoCo's C engine, the paper preset (the tuned teacher: its own
preset). A benchmark *entry* is a (student, grid method) pair; each student's cells are a grid of their own,
``<runs-dir>/<student>/paper/<task>/<method>`` (default ``runs/benchmark-<name>``), archived in
``<results-dir>/<student>/cells/<task>/<method>`` (default ``results/<name>``), so the same strategy can be an entry
of two students.

Every cell is an ``experiments.reproduce`` cell (``experiments.training.grid_cells``): planned from what is on disk
(done: skipped; a checkpoint: resumed; a shorter finished run: extended; else run), run by ``experiments.run`` in
this process or, with ``--launcher ray``, as a Ray task (reproduce's options), recorded in ``reproduce.json``
(commit, dirty diff, command, wall and CPU time) and archived as soon as it finishes. Every cell's config is
validated before the first one runs (bad input: one ``error:`` line, exit 2). The artefacts
(``experiments.analysis.benchmark``): per task the final returns and the verdicts against the student's baseline
(its Gaussian noise, or the reference named by ``--baseline``, e.g. a best fixed noise chosen in advance), the
aggregate over the tasks, sample-efficiency curves, the cost of each cell, ``README.md`` and ``manifest.json``
(docs/reproducing.md, "The exploration benchmark").

``--dry-run`` prints the plan and, unless ``--no-calibrate``, an estimated time per cell: each entry with work left
runs ``experiments.run`` in a subprocess for a few chunks of ``--calibration-steps`` env steps on one task (its real
config otherwise: seeds, networks, replay capacity; a cold compile), and each other task with work left runs its
student's Gaussian noise the same way; a cell's estimate is the calibration task's compile time and per-step time of
its entry, scaled by the task's over the calibration task's for the Gaussian noise, times its remaining steps; CPU
time is that times the entry's CPU utilisation during its calibration.

Exit status: 0 every planned cell finished (``--dry-run``: the plan printed); 1 ``--dry-run`` whose calibration
runs all failed; 2 bad input; 3 some cell stopped on non-finite parameters (the others
still ran); 130 interrupted (143 by SIGTERM) (the artefacts are still rebuilt; run the same command again to
resume).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import re
import sys

import envs
from experiments import reproduce
from experiments.analysis import benchmark as artefacts
from experiments.analysis.render import benchmark as bench_report
from experiments.grid import methods as grid
from experiments.grid.methods import (NAMED_ONLY, STRATEGIES, STUDENT_BASELINES, STUDENT_NAMES, baseline_for,
                                    task_folder)
from experiments.grid import engine
from experiments.grid.cli import add_grid_options, check_grid_options, grid_run, grid_spec
from experiments.grid.estimate import add_estimate_options, check_estimate_options
from experiments.training import grid_cells

DEFAULT_NAME = "exploration"
DEFAULT_STUDENTS = ("td3", "sac")
DEFAULT_SEEDS = 10
DEFAULT_SEED = 1000  # results/ has base seeds 0 (Table 2, modern, mujoco, td3, the screen) and 100 (tuned)
DEFAULT_STEPS = 300_000


def build_parser() -> argparse.ArgumentParser:
    strategies = "; ".join(f"{s}: {', '.join(m)}" for s, m in STRATEGIES.items())
    learned = "; ".join(f"{s}: {', '.join(m)}" for s, m in NAMED_ONLY.items())
    p = argparse.ArgumentParser(prog="python -m experiments.benchmark", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--tasks", default=",".join(grid.tasks()),
                   help=f"comma-separated tasks, {', '.join(envs.TASKS)}, gym:<Id> or dmc:<domain>-<task> (default: "
                        "the paper's six)")
    p.add_argument("--students", default=",".join(DEFAULT_STUDENTS),
                   help=f"comma-separated students (default {','.join(DEFAULT_STUDENTS)})")
    p.add_argument("--strategies", default=None,
                   help=f"comma-separated strategies (grid methods) of those students (default: all; each student's "
                        f"baseline is always planned): {strategies}; and, only when named, the "
                        f"learned-exploration variants and controls (results/learned/README.md): {learned}")
    p.add_argument("--baseline", action="append", default=[], metavar="STUDENT=STRATEGY",
                   help="the student's reference, chosen in advance (e.g. td3=td3-pink, the best fixed noise of an "
                        "earlier benchmark): always planned; every other strategy of the student gets its verdicts "
                        "and probability of improvement against it (default: its Gaussian noise, "
                        + ", ".join(f"{s}={m}" for s, m in STUDENT_BASELINES.items()) + ")")
    p.add_argument("--preset", default=artefacts.PRESET, choices=tuple(grid.BASELINES),
                   help=f"the preset of every cell but those of a method with its own (default {artefacts.PRESET}): "
                        "e.g. modern, to check that the strategies' order holds under the cheaper paper preset")
    p.add_argument("--name", default=DEFAULT_NAME, help=f"the benchmark's name (default {DEFAULT_NAME}): its folders")
    p.add_argument("--anchors", default=None, metavar="PATH",
                   help="normalisation anchors of the aggregate and the equivalence margins (default "
                        "results/normalisation.json, Table 2's tasks; results/normalisation-hard.json: the hard "
                        "set's)")
    p.add_argument("--task-steps", action="append", default=[], metavar="TASK=STEPS",
                   help="a task's own budget, env steps per seed, instead of --steps (repeatable, or comma-separated)")
    p.add_argument("--task-seeds", action="append", default=[], metavar="TASK=SEEDS",
                   help="a task's own seed count, instead of --seeds (repeatable, or comma-separated): e.g. the "
                        "counts a pilot's spread asks for (experiments.analysis.power.seeds_for)")
    p.add_argument("--task-set", action="append", default=[], metavar="TASK:GROUP.FIELD=VALUE",
                   help="a config override of one task's cells, after --set's (repeatable, one override each): e.g. "
                        "its evaluation interval, dmc:reacher-hard:run.eval_every=5000")
    add_grid_options(p, seeds=DEFAULT_SEEDS, seed=DEFAULT_SEED, steps=DEFAULT_STEPS, physics="mujoco",
                     steps_help=f"env steps per seed of every cell (default {DEFAULT_STEPS:,})",
                     physics_help="engine of the MuJoCo tasks (default mujoco, MuJoCo's C engine; gym: tasks need it)",
                     runs_help="the cells' run folders (default runs/benchmark-<name>)",
                     results_help="archive and artefacts (default results/<name>)")
    p.add_argument("--artefacts-only", action="store_true", help="train nothing; rebuild the artefacts only")
    p.add_argument("--dry-run", action="store_true",
                   help="print the plan (each cell's state and command) and the estimated time; do nothing else")
    add_estimate_options(p, by_default=True)
    return p


def parse_tasks(text: str) -> list[str]:
    """The ``--tasks`` list: built-in, ``gym:<Id>`` and ``dmc:<domain>-<task>`` tasks (``envs.get_spec`` checks
    them), each once."""

    tasks = [t.strip() for t in re.split(r",(?![^()]*\))", text) if t.strip()]  # commas inside gym:Id(...) stay
    if not tasks:
        raise ValueError("--tasks names no task")
    for t in tasks:
        if t not in envs.TASKS and not envs.is_gym_task(t) and not envs.is_dmc_task(t):
            raise ValueError(f"unknown task {t!r}; valid tasks: {', '.join(envs.TASKS)}, gym:<Id> or "
                             f"dmc:<domain>-<task>")
        envs.get_spec(t)
    if len(set(tasks)) != len(tasks) or len({task_folder(t) for t in tasks}) != len(tasks):
        raise ValueError("--tasks lists a task twice")
    return tasks


def parse_baselines(items: list[str]) -> dict[str, str]:
    """``--baseline STUDENT=STRATEGY`` (repeatable, or comma-separated) as {student: strategy}."""
    out = {}
    for item in (x.strip() for i in items for x in i.split(",") if x.strip()):
        student, sep, method = item.partition("=")
        if not sep or not student.strip() or not method.strip():
            raise ValueError(f"--baseline expects STUDENT=STRATEGY, got {item!r}")
        if student.strip() in out:
            raise ValueError(f"--baseline names student {student.strip()!r} twice")
        out[student.strip()] = method.strip()
    return out


def _task_items(items: list[str], option: str, usage: str, split, commas: bool = True) -> list[tuple[str, str]]:
    """(task, value) of each item of a per-task option, comma-separated if ``commas`` (commas inside a gym: task's
    arguments stay), ``split(item) -> (task, separator found, value)``; ``ValueError`` (one line) for a malformed
    one."""
    out = []
    for item in (x.strip() for i in items for x in (re.split(r",(?![^()]*\))", i) if commas else [i]) if x.strip()):
        task, found, value = split(item)
        if not found or not task.strip() or not value.strip():
            raise ValueError(f"{option} expects {usage}, got {item!r}")
        out.append((task.strip(), value.strip()))
    return out


def _split_set(item: str) -> tuple[str, str, str]:
    """'TASK:GROUP.FIELD=VALUE' -> (TASK, ':', GROUP.FIELD=VALUE); the task's own colons (dmc:..., gym:...) stay."""
    m = re.fullmatch(r"(.+):([A-Za-z_]\w*\.[A-Za-z_]\w*=.*)", item)
    return (m.group(1), ":", m.group(2)) if m else (item, "", "")


def task_settings(a: argparse.Namespace, tasks: list[str]) -> dict[str, dict]:
    """{task: {"steps", "seeds", "overrides"}} from ``--task-steps``, ``--task-seeds`` and ``--task-set``: each task's
    budget, seed count and overrides (``--steps``, ``--seeds`` and ``--set`` where it has none of its own).
    ``ValueError`` (one line) for a task not in ``--tasks``, a task named twice, a bad count or override."""
    from experiments.training import args as training_args

    out = {t: {"steps": a.steps, "seeds": a.seeds, "overrides": tuple(a.overrides)} for t in tasks}
    for option, items, key in (("--task-steps", a.task_steps, "steps"), ("--task-seeds", a.task_seeds, "seeds")):
        seen = set()
        for task, value in _task_items(items, option, "TASK=N", lambda item: item.rpartition("=")):
            if task not in out:
                raise ValueError(f"{option} names {task!r}, which is not one of --tasks ({', '.join(tasks)})")
            if task in seen:
                raise ValueError(f"{option} names {task!r} twice")
            seen.add(task)
            if not value.isdigit() or int(value) <= 0:
                raise ValueError(f"{option} {task}={value}: a positive whole number is needed")
            out[task][key] = int(value)
    for task, item in _task_items(a.task_set, "--task-set", "TASK:GROUP.FIELD=VALUE", _split_set, commas=False):
        if task not in out:
            raise ValueError(f"--task-set names {task!r}, which is not one of --tasks ({', '.join(tasks)})")
        training_args.parse_overrides([item])
        out[task]["overrides"] += (item,)
    return out


def narrow_task_options(a: argparse.Namespace) -> None:
    """Keeps the per-task options' items (``--task-steps``, ``--task-seeds``, ``--task-set``) of ``--tasks`` only: a
    study narrowed by ``--tasks`` (``python -m experiments.grid``) runs those tasks with their own settings and
    leaves its other tasks' out, where the plain command refuses a setting of a task it does not run."""
    keep = {t.strip() for t in re.split(r",(?![^()]*\))", a.tasks)}
    a.task_steps, a.task_seeds = ([f"{t}={v}" for t, v in _task_items(items, option, "TASK=N",
                                                                     lambda item: item.rpartition("=")) if t in keep]
                                  for option, items in (("--task-steps", a.task_steps), ("--task-seeds", a.task_seeds)))
    a.task_set = [f"{t}:{v}" for t, v in _task_items(a.task_set, "--task-set", "TASK:GROUP.FIELD=VALUE", _split_set,
                                                     commas=False) if t in keep]


def entries(a: argparse.Namespace) -> list[artefacts.Entry]:
    students = reproduce.parse_list(a.students, tuple(STRATEGIES), "student")
    baselines = parse_baselines(a.baseline)
    if a.strategies is None:
        return artefacts.entries_for(students, baselines=baselines)
    valid = tuple(dict.fromkeys(m for s in students for m in (*STRATEGIES[s], *NAMED_ONLY.get(s, ()))))
    return artefacts.entries_for(students, reproduce.parse_list(a.strategies, valid, "strategy"), baselines)


def plan(a: argparse.Namespace) -> tuple[list[str], list[artefacts.Entry], list[grid_cells.Cell]]:
    """(tasks, entries, cells in run order: task by task, each task's entries); every cell's config validated
    (``ValueError``, one line) unless the cell finished at the budget already."""
    if not re.fullmatch(r"[\w.-]+", a.name):
        raise ValueError(f"--name {a.name!r}: letters, digits, '_', '.' and '-' only (it names folders)")
    a.runs_dir = a.runs_dir or os.path.join("runs", f"benchmark-{a.name}")
    a.results_dir = a.results_dir or os.path.join("results", a.name)
    tasks = parse_tasks(a.tasks)
    chosen = entries(a)
    check_grid_options(a, trains=not a.artefacts_only and not a.dry_run)
    check_estimate_options(a, tasks)
    if a.anchors is not None and not os.path.isfile(a.anchors):
        raise ValueError(f"--anchors {a.anchors}: no such file")
    grids = {}
    for student in dict.fromkeys(e.student for e in chosen):
        runs, results = artefacts.student_dirs(a.runs_dir, a.results_dir, student)
        grids[student] = (grid_run(a, runs, results, a.preset, baseline_for(a.preset, student)),
                          grid_spec(a, a.preset, student))
    per_task = task_settings(a, tasks)
    cells = [grid_cells.grid_cell(grids[e.student][0], dataclasses.replace(grids[e.student][1], **per_task[t]), t,
                                  e.method, key=(e.student, t, e.method), tag=f"{e.student}/{t}/{e.method}")
             for t in tasks for e in chosen]
    if not a.artefacts_only:
        # A budget that one strategy's cycle does not divide, a bad --set or a task the engine cannot step stops the
        # benchmark here, before the first cell trains.
        grid_cells.validate_cells(cells)
    return tasks, chosen, cells



def main(argv: list[str] | None = None) -> int:
    return run_parsed(build_parser().parse_args(argv), sys.argv[1:] if argv is None else list(argv))


def run_parsed(a: argparse.Namespace, argv: list[str]) -> int:
    """``main`` after parsing (``experiments.grid`` runs a named study through it); ``argv``: what the manifest
    records as the command's options."""
    return engine.run(a, lambda: grid_plan(a, argv), report_only=a.artefacts_only)


def grid_plan(a: argparse.Namespace, argv: list[str]) -> engine.GridPlan:
    """The benchmark's cells (``plan``) and its report (``experiments.analysis.render.benchmark.build``)."""
    tasks, chosen, cells = plan(a)
    per = ", ".join(f"{STUDENT_NAMES.get(s, s)}: {sum(e.student == s for e in chosen)}"
                    for s in dict.fromkeys(e.student for e in chosen))
    # Each task's own budget, seeds and overrides where it has them (--task-steps, --task-seeds, --task-set).
    own = {t: {"steps": d["steps"], "seeds": d["seeds"], "overrides": list(d["overrides"][len(a.overrides):])}
           for t, d in task_settings(a, tasks).items()
           if (d["steps"], d["seeds"], d["overrides"]) != (a.steps, a.seeds, tuple(a.overrides))}
    banner = (f"exploration benchmark {a.name!r}: {len(tasks)} tasks x {len(chosen)} entries ({per}) = {len(cells)} "
              f"cells of {a.seeds} seeds, {a.steps:,} env steps per seed, {a.physics} physics, base seed {a.seed}"
              + "".join(f"; {t}: {d['seeds']} seeds, {d['steps']:,} steps" + "".join(f", {x}" for x in d["overrides"])
                        for t, d in own.items())
              + (f", {a.preset} preset" if a.preset != artefacts.PRESET else "")
              + f"; cells in {a.runs_dir}/<student>/{a.preset}/<task>/<method>, results in {a.results_dir}")

    def report(wall_seconds: float) -> None:
        from experiments.aggregate import repo_path  # the reports name their inputs relative to the repository

        options = {"name": a.name, "students": list(dict.fromkeys(e.student for e in chosen)),
                   "strategies": [e.key for e in chosen], "baselines": artefacts.baselines_of(chosen),
                   "seeds": a.seeds, "seed": a.seed, "steps": a.steps, "physics": a.physics,
                   "overrides": a.overrides, **({"task_settings": own} if own else {}),
                   **({"anchors": repo_path(a.anchors)} if a.anchors is not None else {}),
                   **({"preset": a.preset} if a.preset != artefacts.PRESET else {}), "argv": argv}
        manifest = bench_report.build(a.runs_dir, a.results_dir, chosen, tasks, plan=options,
                                      anchors_path=a.anchors, preset=a.preset,
                                      extra_provenance={"benchmark_wall_seconds": wall_seconds})
        print(f"artefacts: {len(manifest['files'])} files in {a.results_dir} ({len(manifest['cells'])} stored cells, "
              f"{len(manifest['not_run'])} not run)", flush=True)

    return engine.GridPlan(cells, tasks, report, word="benchmark", banner=banner)

if __name__ == "__main__":
    sys.exit(main())
