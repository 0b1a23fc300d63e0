"""Run (or resume) the paper's grid of task x method x seeds, then rebuild every artefact.

    python -m experiments.reproduce                                   # the whole grid, paper preset, 8 seeds
    python -m experiments.reproduce --tasks pendulum,reacher --methods meta-independent,ddpg-paramnoise
    python -m experiments.reproduce --preset modern                  # results/modern/
    python -m experiments.reproduce --preset tuned --physics mujoco --results-dir results   # results/tuned/
    python -m experiments.reproduce --artefacts-only --embedding pca  # no training, rebuild from what is stored

Each grid cell is one ``experiments.run.main`` call writing
``<runs-dir>/<preset>/<task>/<method>``, run one after another in ``RUN_ORDER``
(InvertedDoublePendulum first). Run folders are not committed
(checkpoints are large); every finished cell's results (config, metrics,
summary, provenance, a thinned state-visitation sample) are copied into the
committed archive ``<results-dir>/cells/<task>/<method>`` when the artefacts
are rebuilt and as soon as a cell finishes. A cell whose ``summary.json``
exists is skipped (so is one with no run folder whose results are archived);
one with a checkpoint but no summary is resumed (with the
same explicit options, so ``--resume`` checks they match); one with neither
(killed before its first checkpoint) is started again. A finished cell whose
budget is below the requested one (e.g. a reduced-budget cell, when the grid is
run again at the paper's budget) is *extended* from its final checkpoint
(``experiments.run --resume <cell> --steps=<budget>``: the same numbers as a run
started at that budget); until the extension finishes, the archive keeps the
shorter cell. Next to each cell's
run outputs, ``reproduce.json`` records the commit, the machine, the command
and the accumulated wall time of this script's calls for that cell.

``--launcher ray`` runs every cell that has work left as a Ray task (``experiments.training.grid_cells.run_cells_ray``; a local Ray
instance unless ``--ray-address`` names a cluster): the same planning and archiving in the worker, and
a cell whose worker died is retried by Ray and resumes from its checkpoint (docs/reproducing.md).
``--student td3`` runs the TD3 grid (``experiments.grid.methods.GRIDS``) into ``runs/reproduce-td3`` and
``results/td3``.

Then ``experiments.artefacts.build_all`` rebuilds Table 2, the learning
curves, steps-to-threshold, the teacher-design and state-visitation figures,
``README.md`` and ``manifest.json`` under ``--results-dir`` (``<results-dir>/
<preset>`` for a preset other than ``paper``) from whatever is stored.

Exit status: 0 every requested cell finished; 2 bad input; 3 some cell stopped
on non-finite parameters (the others still ran); 130 interrupted (143 by SIGTERM) (artefacts
are still rebuilt from what is stored; run the same command again to resume).
"""

from __future__ import annotations

import argparse
import sys

from experiments.artefacts import add_figure_options, build_all
from experiments.analysis.cells import results_dir_for
from experiments.grid import methods as grid
from experiments.grid.methods import BASELINES, GRIDS, baseline_for, methods_for
from experiments.grid import engine
from experiments.grid.cli import add_grid_options, check_grid_options, grid_run, grid_spec
from experiments.grid.estimate import add_estimate_options, check_estimate_options
from experiments.training import grid_cells

# Where --physics=mujoco keeps its grid by default, apart from the MJX grid's runs/reproduce and results.
MUJOCO_RUNS, MUJOCO_RESULTS = "runs/reproduce-mujoco", "results/mujoco"
# Where a student other than DDPG keeps its grid by default (whatever the physics): runs/reproduce-<student>
# and results/<student>.
# The order a full grid runs its tasks in: this study's choice (the grid's tasks are the paper's,
# experiments.grid.methods.tasks; test_reproduce checks that this lists each once).
RUN_ORDER = ("inverted_double_pendulum", "pendulum", "inverted_pendulum", "reacher", "hopper", "halfcheetah")
DEFAULT_SEEDS = 8


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m experiments.reproduce",
        description="Run or resume the paper's task x method grid (skipping finished cells), then rebuild "
                    "Table 2 and the figures from the stored results.")
    p.add_argument("--tasks", default=",".join(RUN_ORDER),
                   help=f"comma-separated tasks, run in this order (default: {','.join(RUN_ORDER)})")
    p.add_argument("--methods", default=None,
                   help="comma-separated methods of the student's grid (default: all of them): "
                        + "; ".join(f"{s}: {', '.join(m)}" for s, m in GRIDS.items()))
    p.add_argument("--student", default="ddpg", choices=tuple(GRIDS),
                   help="the learner of every cell: ddpg (default) or td3 (its grid: TD3 with Gaussian noise 0.1 vs "
                        "Meta on TD3; cells go to runs/reproduce-td3 and results/td3 unless --runs-dir/--results-dir "
                        "are given)")
    p.add_argument("--preset", default="paper", choices=tuple(BASELINES),
                   help="'paper' (default; results in --results-dir), 'modern' or 'tuned' (results in "
                        "<results-dir>/<preset>)")
    p.add_argument("--source", default="gymnasium", help="MuJoCo models: gymnasium (default) or brax")
    add_grid_options(
        p, seeds=DEFAULT_SEEDS, seed=0, steps=None, physics="mjx",
        steps_help="env steps per seed for every cell (default: each task's paper budget)",
        physics_help="engine of the MuJoCo tasks: mjx (default) or mujoco (MuJoCo's C engine; its cells go to "
                     f"{MUJOCO_RUNS} and {MUJOCO_RESULTS} unless --runs-dir/--results-dir are given; "
                     "pendulum cells run on their JAX physics either way)",
        runs_help="grid root (default runs/reproduce)", results_help="artefact folder (default results)")
    p.add_argument("--artefacts-only", action="store_true", help="train nothing; rebuild the artefacts only")
    add_figure_options(p)
    p.add_argument("--dry-run", action="store_true", help="print what would be run, skipped or resumed; do nothing")
    add_estimate_options(p, by_default=False)
    return p


def parse_list(text: str, valid, what: str) -> list[str]:
    items = [t.strip() for t in text.split(",") if t.strip()]
    bad = [t for t in items if t not in valid]
    if bad or not items:
        raise ValueError(f"unknown {what} {', '.join(map(repr, bad)) or '(none given)'}; valid: {', '.join(valid)}")
    if len(set(items)) != len(items):
        raise ValueError(f"--{what}s lists a {what} twice")
    return items


def main(argv: list[str] | None = None) -> int:
    return run_parsed(build_parser().parse_args(argv), sys.argv[1:] if argv is None else list(argv))


def run_parsed(args: argparse.Namespace, argv: list[str]) -> int:
    """``main`` after parsing (``experiments.grid`` runs a named study through it); ``argv``: what the manifest
    records as the command's options."""
    return engine.run(args, lambda: plan(args, argv), report_only=args.artefacts_only)


def plan(args: argparse.Namespace, argv: list[str]) -> engine.GridPlan:
    """The grid's cells (validated unless only the artefacts are rebuilt) and its report, Table 2's artefacts."""
    mujoco = args.physics == "mujoco"
    other = args.student != "ddpg"
    if args.runs_dir is None:
        args.runs_dir = f"runs/reproduce-{args.student}" if other else MUJOCO_RUNS if mujoco else "runs/reproduce"
    if args.results_dir is None:
        args.results_dir = f"results/{args.student}" if other else MUJOCO_RESULTS if mujoco else "results"
    tasks = parse_list(args.tasks, grid.tasks(), "task")
    if mujoco and args.source != "gymnasium":
        raise ValueError(f"--physics=mujoco steps gymnasium's models; source {args.source!r} has only MJX")
    grid_methods = methods_for(args.student)
    methods = parse_list(args.methods or ",".join(grid_methods), grid_methods, "method")
    check_grid_options(args, trains=not args.artefacts_only and not args.dry_run)
    placement = grid_run(args, args.runs_dir, args.results_dir, args.preset, baseline_for(args.preset, args.student))
    spec = grid_spec(args, args.preset, args.student, args.source)
    cells = [grid_cells.grid_cell(placement, spec, t, m) for t in tasks for m in methods]
    check_estimate_options(args, tasks)
    if not args.artefacts_only:
        grid_cells.validate_cells(cells)

    def report(wall_seconds: float) -> None:
        manifest = build_all(
            args.runs_dir, args.results_dir, args.preset, embedding=args.embedding,
            visitation_tasks=args.visitation_task, student=args.student,
            extra_provenance={"reproduce_argv": argv,
                              "requested": {"tasks": tasks, "methods": methods, "seeds": args.seeds,
                                            "seed": args.seed, "steps": args.steps, "overrides": args.overrides},
                              "grid_wall_seconds": wall_seconds})
        out = results_dir_for(args.results_dir, args.preset)
        print(f"artefacts: {len(manifest['files'])} files in {out} ({len(manifest['cells'])} stored cells, "
              f"{len(manifest['not_run'])} not run): {', '.join(manifest['files'])}", flush=True)

    return engine.GridPlan(cells, tasks, report)

if __name__ == "__main__":
    sys.exit(main())
