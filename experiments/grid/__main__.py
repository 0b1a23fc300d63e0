"""Run, resume or rebuild any named study (``experiments.grid.studies``) with one command.

    python -m experiments.grid --list                          # the studies, one line each
    python -m experiments.grid table2-c --dry-run              # its plan: each cell's state and command
    python -m experiments.grid table2-c                        # run it (resumable: the same command goes on)
    python -m experiments.grid learned-judgement --report-only # rebuild its results from the archive
    python -m experiments.grid exploration --tasks hopper --launcher ray --ray-address auto
    python -m experiments.grid screen --help                   # every option of the study's kind

A study fixes the options that define it (its kind's: tasks, methods or strategies, students, baselines, seeds,
base seed, budget, engine, overrides, folders); every other option of its kind (``experiments.reproduce``,
``experiments.screen`` or ``experiments.benchmark``) is given as for that command: ``--dry-run``, ``--launcher``,
``--ray-*``, ``--quiet``, checkpoint cadence, ``--runs-dir`` (where the run folders live, not committed; the archive
and the report stay the study's). ``--tasks`` may narrow the study's tasks (each kept task with its own budget and
overrides): the narrowed call runs and archives those tasks' cells and leaves the study's report as it is (the report
covers every cell of the study: the whole study's command rebuilds it, skipping finished cells), unless
``--results-dir`` names a folder of its own, which then gets a report of the kept tasks alone;
``--report-only`` trains nothing and rebuilds the report. An option that would change the study
(``--seed 5`` on a study of base seed 2000) is refused: that is another grid, for the kind's own command.

Exit status: the kind's (0 done, 2 bad input, 3 a cell stopped on non-finite parameters, 130/143 interrupted).
"""

from __future__ import annotations

import importlib
import sys

from experiments.grid.studies import Study, studies


def list_lines(found: dict[str, Study]) -> list[str]:
    width = max(map(len, found))
    return [f"  {name:<{width}}  {study.kind:<9}  {study.about}" for name, study in found.items()]


def parse_study(study: Study, rest: list[str]):
    """(the kind's module, its parsed options with the study's settings applied); ``ValueError`` (one line) for an
    option that would change the study."""
    module = importlib.import_module(f"experiments.{study.kind}")
    parser = module.build_parser()
    parser.prog = f"python -m experiments.grid {study.name}"
    report = "--report-only" if study.kind == "screen" else "--artefacts-only"
    a = parser.parse_args([report if x == "--report-only" else x for x in rest])
    defaults = vars(parser.parse_args([]))
    tasks = study.settings.get("tasks", defaults["tasks"]).split(",")
    kept = [t.strip() for t in a.tasks.split(",") if t.strip()] if a.tasks != defaults["tasks"] else tasks
    outside = [t for t in kept if t not in tasks]
    if outside:
        raise ValueError(f"study {study.name!r} has no task {outside[0]!r}; its tasks: {','.join(tasks)}")
    narrowed = kept != tasks
    if narrowed and a.results_dir in (defaults["results_dir"], study.settings.get("results_dir")):  # the study's own
        if "--report-only" in rest or "--artefacts-only" in rest:
            raise ValueError(f"--report-only with --tasks would rebuild study {study.name!r}'s report from part of its "
                             "cells: drop --tasks, or give --results-dir DIR for a report of those tasks alone")
        a.skip_report = f"--tasks narrowed study {study.name!r}: its report is not rebuilt from part of its cells " \
                        f"(python -m experiments.grid {study.name} --report-only rebuilds it)"
    for dest, value in study.settings.items():
        given = getattr(a, dest)
        if dest == "runs_dir" and given != defaults[dest]:
            continue  # where the run folders live does not change the grid
        if dest == "tasks" and given != defaults[dest]:
            continue  # a narrowing (checked above)
        if given != defaults[dest] and given != value:
            option = "--" + dest.replace("_", "-").replace("overrides", "set")
            raise ValueError(f"study {study.name!r} is defined with {option} {value!r}; another value makes another "
                             f"grid: run python -m experiments.{study.kind} with the options you want")
        setattr(a, dest, value)
    if study.kind == "benchmark" and "tasks" in study.settings:
        module.narrow_task_options(a)
    return module, a


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    found = studies()
    if not argv or argv[0] in ("-h", "--help", "--list"):
        print(__doc__.strip().splitlines()[0] + "\n\nusage: python -m experiments.grid STUDY [options of its kind]\n\n"
              "studies:\n" + "\n".join(list_lines(found)))
        return 0 if argv else 2
    name, rest = argv[0], argv[1:]
    if name not in found:
        print(f"error: unknown study {name!r}; studies: {', '.join(found)} (python -m experiments.grid --list)",
              file=sys.stderr)
        return 2
    try:
        module, a = parse_study(found[name], rest)
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return module.run_parsed(a, argv)


if __name__ == "__main__":
    sys.exit(main())
