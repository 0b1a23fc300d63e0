"""The grid engine: what every grid command does with its cells, in one place.

A grid command (``experiments.reproduce``, ``experiments.screen``, ``experiments.benchmark``, and through them
every named study of ``experiments.grid.studies``) says only which cells it has and how its report is built
(``GridPlan``); ``run`` does the rest, the same way for each:

1. plan: the command's ``plan`` builds every cell (typed data: ``experiments.grid.spec``) and validates every
   cell's config before any trains (bad input: one ``error:`` line, exit 2);
2. ``--dry-run``: each cell's state (done, new, resume, restart, extend) and command, with a calibrated time
   estimate where asked for (``experiments.grid.estimate``), and nothing else;
3. run: the cells with work left, one after another here or as Ray tasks (``experiments.grid.cli.launch``);
   each is resumed from its checkpoint, recorded with its provenance and archived as soon as it finishes
   (``experiments.training.grid_cells``);
4. report: the command's report rebuilt from whatever the archive holds (also after a Ctrl-C, and alone with
   ``--report-only`` / ``--artefacts-only``); not after a SIGTERM, which a scheduler follows with a kill, nor for a
   study narrowed to some of its tasks (``a.skip_report``, set by ``experiments.grid``: the line it prints says why).

Exit status: 0 every cell finished (a dry run: the plan printed); 1 a dry run whose calibration runs all failed;
2 bad input; 3 some cell stopped on non-finite parameters (the others still ran); 130 interrupted by Ctrl-C: the
report is still rebuilt; 143 stopped by SIGTERM (the cell's run checkpointed its chunk in flight within
``--term-grace``, or stopped at once): the report is not built. The same command resumes the stopped cell.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from typing import Callable


@dataclasses.dataclass(frozen=True)
class GridPlan:
    """A grid command's cells and report.

    Attributes:
      cells: every cell (``grid_cells.Cell``), in run order, validated.
      tasks: the tasks the cells cover, in order (the estimate calibrates on them).
      report: ``(wall seconds of this call's training) -> None``: rebuilds the report from the archive and prints
        what it wrote.
      word: what the launch's summary line calls the grid ('grid', 'screen', 'benchmark').
      banner: a line printed once the plan is made (what the grid is), or None.
    """

    cells: list
    tasks: list[str]
    report: Callable[[float], None]
    word: str = "grid"
    banner: str | None = None


def run(a: argparse.Namespace, plan: Callable[[], GridPlan], report_only: bool) -> int:
    """Plans, then dry-runs or runs the cells and rebuilds the report (the module docstring's steps); the exit
    status. ``a``: the command's parsed options (``experiments.grid.cli``'s shared ones among them);
    ``report_only``: train nothing, rebuild the report."""
    from experiments.grid import estimate
    from experiments.grid.cli import launch

    try:
        p = plan()
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if p.banner:
        print(p.banner, flush=True)
    if a.dry_run:
        return estimate.dry_run(a, p.tasks, p.cells)
    t0, status = time.perf_counter(), 0
    if not report_only:
        status, _ = launch(p.cells, a, p.word)
    if status == 143:
        print(f"{p.word} stopped by SIGTERM: its report is not built; run the same command again to resume it",
              file=sys.stderr, flush=True)
        return status
    if getattr(a, "skip_report", None):
        print(a.skip_report, flush=True)
        return status
    p.report(round(time.perf_counter() - t0, 2))
    return status
