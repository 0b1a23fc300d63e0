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

``--launcher ray`` runs every cell that has work left as a Ray task (``experiments.training.grid_cells.run_grid_ray``; a local Ray
instance unless ``--ray-address`` names a cluster): the same planning and archiving in the worker, and
a cell whose worker died is retried by Ray and resumes from its checkpoint (docs/reproducing.md).
``--student td3`` runs the TD3 grid (``experiments.build.grid.GRIDS``) into ``runs/reproduce-td3`` and
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
import time

from experiments.artefacts import add_figure_options, build_all
from experiments.build.cells import results_dir_for
from experiments.build import grid
from experiments.build.grid import BASELINES, GRIDS, methods_for
from experiments.training import grid_cells

# Where --physics=mujoco keeps its grid by default, apart from the MJX grid's runs/reproduce and results.
MUJOCO_RUNS, MUJOCO_RESULTS = "runs/reproduce-mujoco", "results/mujoco"
# Where a student other than DDPG keeps its grid by default (whatever the physics): runs/reproduce-<student>
# and results/<student>.
# The order a full grid runs its tasks in: this study's choice (the grid's tasks are the paper's,
# experiments.build.grid.tasks; test_reproduce checks that this lists each once).
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
    p.add_argument("--seeds", type=int, default=DEFAULT_SEEDS, help=f"seeds per cell (default {DEFAULT_SEEDS})")
    p.add_argument("--seed", type=int, default=0, help="base PRNG seed of every cell (default 0)")
    p.add_argument("--steps", type=int, default=None,
                   help="env steps per seed for every cell (default: each task's paper budget)")
    p.add_argument("--preset", default="paper", choices=tuple(BASELINES),
                   help="'paper' (default; results in --results-dir), 'modern' or 'tuned' (results in "
                        "<results-dir>/<preset>)")
    p.add_argument("--source", default="gymnasium", help="MuJoCo models: gymnasium (default) or brax")
    p.add_argument("--physics", default="mjx", choices=("mjx", "mujoco"),
                   help="engine of the MuJoCo tasks: mjx (default) or mujoco (MuJoCo's C engine; its cells go to "
                        f"{MUJOCO_RUNS} and {MUJOCO_RESULTS} unless --runs-dir/--results-dir are given; "
                        "pendulum cells run on their JAX physics either way)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="GROUP.FIELD=VALUE",
                   help="config override passed to every cell's experiments.run (e.g. tiny test settings)")
    p.add_argument("--runs-dir", default=None, help="grid root (default runs/reproduce)")
    p.add_argument("--results-dir", default=None, help="artefact folder (default results)")
    p.add_argument("--artefacts-only", action="store_true", help="train nothing; rebuild the artefacts only")
    add_figure_options(p)
    p.add_argument("--no-plot", action="store_true", help="skip each run's own PNGs (the artefacts are still drawn)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--tensorboard", action="store_true",
                   help="each cell also writes TensorBoard scalars to <cell>/tensorboard/seed_<i>/ (experiments.run "
                        "--tensorboard; needs the tensorboard extra, tensorboardX)")
    p.add_argument("--checkpoint-every", type=int, default=0, metavar="CHUNKS",
                   help="each cell checkpoints every CHUNKS chunks (experiments.run --checkpoint-every; default 0: "
                        "every --checkpoint-minutes)")
    p.add_argument("--checkpoint-minutes", type=float, default=5.0,
                   help="each cell's minimum minutes between checkpoints (experiments.run; default 5)")
    p.add_argument("--dry-run", action="store_true", help="print what would be run, skipped or resumed; do nothing")
    p.add_argument("--launcher", default="local", choices=("local", "ray"),
                   help="local (default): the cells one after another in this process; ray: each cell a Ray task "
                        "(the ray extra), on a local Ray instance started here, or on --ray-address")
    p.add_argument("--ray-address", default=None, metavar="HOST:PORT|auto",
                   help="an existing Ray cluster (default: start a local instance); its nodes need this package "
                        "installed and --runs-dir/--results-dir on a shared file system")
    p.add_argument("--ray-cpus-per-cell", type=float, default=1.0, help="CPUs each cell's task asks Ray for (default 1)")
    p.add_argument("--ray-gpus-per-cell", type=float, default=0.0, help="GPUs each cell's task asks Ray for (default 0)")
    p.add_argument("--ray-retries", type=int, default=3,
                   help="times Ray restarts a cell whose worker died (it resumes from its last checkpoint; default 3)")
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
    args = build_parser().parse_args(argv)
    mujoco = args.physics == "mujoco"
    other = args.student != "ddpg"
    if args.runs_dir is None:
        args.runs_dir = f"runs/reproduce-{args.student}" if other else MUJOCO_RUNS if mujoco else "runs/reproduce"
    if args.results_dir is None:
        args.results_dir = f"results/{args.student}" if other else MUJOCO_RESULTS if mujoco else "results"
    try:
        tasks = parse_list(args.tasks, grid.tasks(), "task")
        if mujoco and args.source != "gymnasium":
            raise ValueError(f"--physics=mujoco steps gymnasium's models; source {args.source!r} has only MJX")
        grid_methods = methods_for(args.student)
        methods = parse_list(args.methods or ",".join(grid_methods), grid_methods, "method")
        if args.seeds <= 0:
            raise ValueError(f"--seeds must be positive, got {args.seeds}")
        if args.steps is not None and args.steps <= 0:
            raise ValueError(f"--steps must be positive, got {args.steps}")
        for item in args.overrides:
            if "=" not in item:
                raise ValueError(f"--set expects GROUP.FIELD=VALUE, got {item!r}")
        if args.launcher == "ray" and not args.artefacts_only and not args.dry_run:
            try:
                import ray  # noqa: F401
            except ImportError:
                raise ValueError("--launcher ray needs Ray: pip install -e \".[ray]\"") from None
        if args.ray_cpus_per_cell < 0 or args.ray_gpus_per_cell < 0 or args.ray_retries < 0:
            raise ValueError("--ray-cpus-per-cell, --ray-gpus-per-cell and --ray-retries must be >= 0")
        if args.tensorboard and not args.artefacts_only:
            from metapg_jax.host import tb_events

            tb_events.require_tensorboard()
        if not args.artefacts_only:
            # Every cell's config before the first one trains: a budget that one method's cycle does not
            # divide, or a bad --set, stops the grid here rather than after the cells before it have run.
            for task in tasks:
                for method in methods:
                    if grid_cells.finished_at_budget(args, task, method):
                        continue  # skipped by run_grid whatever its config would be at this budget
                    try:
                        grid_cells.requested_config(args, task, method)
                    except ValueError as err:
                        raise ValueError(f"{task}/{method}: {err}") from None
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    status, report = 0, {}
    if not args.artefacts_only:
        launch = grid_cells.run_grid_ray if args.launcher == "ray" and not args.dry_run else grid_cells.run_grid
        status, report = launch(args, tasks, methods)
        counts = {}
        for v in report.values():
            counts[v] = counts.get(v, 0) + 1
        print("grid: " + (", ".join(f"{n} {k}" for k, n in sorted(counts.items())) or "nothing to do"), flush=True)
    if args.dry_run:
        return status
    manifest = build_all(
        args.runs_dir, args.results_dir, args.preset, embedding=args.embedding,
        visitation_tasks=args.visitation_task, student=args.student,
        extra_provenance={"reproduce_argv": sys.argv[1:] if argv is None else list(argv),
                          "requested": {"tasks": tasks, "methods": methods, "seeds": args.seeds, "seed": args.seed,
                                        "steps": args.steps, "overrides": args.overrides},
                          "grid_wall_seconds": round(time.perf_counter() - t0, 2)})
    out = results_dir_for(args.results_dir, args.preset)
    print(f"artefacts: {len(manifest['files'])} files in {out} ({len(manifest['cells'])} stored cells, "
          f"{len(manifest['not_run'])} not run): {', '.join(manifest['files'])}", flush=True)
    return status


if __name__ == "__main__":
    sys.exit(main())
